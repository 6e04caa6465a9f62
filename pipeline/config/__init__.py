"""The typed config of every stage (``conf/<stage>.yaml``): its schema, one module a stage
(:mod:`.schemas` names them), composed and checked (:mod:`.compose`), and its ``--help``
(:mod:`.help`)."""
