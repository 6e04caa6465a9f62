"""The camera robot of the paper's future work (issue 30, docs/robot3d.md): a TurtleBot3 Burger in
MuJoCo (:mod:`.model`), the maze built from any layout (:mod:`.world`), moving under physics between
grid cells (:mod:`.sim`), and the navigation task with live camera recognition (:mod:`.env`,
recognisers of live pictures in :mod:`.live`).

It sits above ``rl`` and ``world`` (.importlinter), beside ``report`` and ``replay``, so that adding
it changes none of the modules the trials stages depend on.
"""
