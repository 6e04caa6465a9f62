"""The typed config of every stage (``conf/<stage>.yaml``), one module a stage
(:mod:`pipeline.config.registry` names them), and of the config groups they share: the
``experiment`` (:mod:`.experiment`) and the ``profile`` (:mod:`.profile`).

A schema types its groups by the science's own dataclasses (a method by
:class:`~pipeline.rl.methods.MethodSpec`, meta-training by
:class:`~pipeline.fewshot.settings.TrainConfig`, a report section by
:class:`~pipeline.report.spec.ReportSpec`), so it sits above the science packages and below the
stages, the cells and the Gymnasium entry points, which use it (.importlinter). Its fields are
declared with :mod:`pipeline.config.fields`."""
