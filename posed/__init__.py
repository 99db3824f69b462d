"""posed: one camera on a home robot -> live 3D human pose, joint angles and fall events over Zenoh.

One installed import package. The repository keeps one top-level folder per subpackage (pyproject.toml maps
them with ``package-dir``): ``posed.daemon`` is ``daemon/``, ``posed.hal`` is ``hal/``, ``posed.fitting`` is
``fitting/``, and so on; docs/architecture.md says what each holds and what it may import. Importing
``posed`` itself loads nothing."""
