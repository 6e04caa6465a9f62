"""The typed config of every stage (``conf/<stage>.yaml``): its schema, one module a stage
(:mod:`.schemas` names them), composed and checked (:mod:`.compose`), its ``--help``
(:mod:`.help`), and the recogniser a config names, built (:mod:`.recognisers`).

It sits below the stages and the Gymnasium entry points (``pipeline/envs.py``), which both use it,
and above the science packages whose pieces its schemas type (.importlinter)."""
