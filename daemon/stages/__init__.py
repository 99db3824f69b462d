"""The stage processes: capture, landmarks, fitting, publisher. Each module has ``run(rt: StageRuntime)``;
:func:`daemon.stages.base.stage_main` is the spawn target that sets up the process and calls it."""
