"""``python -m posed``: the ``posed`` command (posed.cli)."""

import sys

from posed.cli import main

sys.exit(main())
