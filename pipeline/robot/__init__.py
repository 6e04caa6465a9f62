"""The camera robot of the paper's future work (issues 30 and 38, docs/robot3d.md) as a world of
the one runner: a TurtleBot3 Burger in MuJoCo (:mod:`.model`), the maze built from any layout
(:mod:`.world`), the controller, range sensor and camera (:mod:`.sim`), the motion table of every
move (:mod:`.motion`), each run's live pictures (:mod:`.live_world`, the runner's ``RobotWorld``),
any recogniser asked about them (:mod:`.live`) and the Gymnasium environment (:mod:`.env`).

It sits above ``rl`` and ``world`` (.importlinter), beside ``report`` and ``replay``: it repeats
neither the runner, the record writer nor the reader.
"""
