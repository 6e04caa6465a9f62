"""How a config is found, composed, checked and explained: the config folder (:mod:`.folder`),
the fields a schema declares its keys with and the one form of a refusal (:mod:`.fields`), the
registry of the stages' schemas (:mod:`.registry`), a stage's config composed and checked
(:mod:`.compose`), its ``--help`` (:mod:`.help`), and the recogniser a config names, built
(:mod:`.recognisers`).

It sits below the science packages, which declare their config fields with it and find the
config folder through it; the schemas that type their pieces are above them, in
:mod:`pipeline.schemas` (.importlinter)."""
