"""The stage processes: capture, landmarks, fitting, publisher. Each stage module (``capture``,
``landmark``, ``fit``, ``publish``) has ``run(rt: StageRuntime)``; :func:`daemon.stages.base.stage_main` is
the spawn target that sets up the process and calls it, and :mod:`daemon.stages.plan` says which run.
``fall_watch`` is the publisher's fall-detection step."""
