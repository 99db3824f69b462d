"""posed daemon: the supervisor, its stage processes, Zenoh publishing, falls and the CLI."""
