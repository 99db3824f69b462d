"""The posed service: the supervisor, its stage processes, the Zenoh bus, the fall-event outbox, the joint-angle
history and the configuration. The ``posed`` command line that starts it is :mod:`posed.cli` (folder ``posed/``)."""
