"""An experiment's cells, as the trials stage runs them: planned, one config each, from the
experiment and the command line (:mod:`.plan`); each run into its folder, its records and summary
(:mod:`.run`), one after another or side by side in worker processes (:mod:`.workers`); followed as
they complete (:mod:`.progress`); and summed up in the experiment's DVC metrics (:mod:`.metrics`).

A cell is a method on a maze (:class:`pipeline.schemas.experiment.Cell`). This package sits below
the stages and above their configs (:mod:`pipeline.config`), the runner and the record writer."""
