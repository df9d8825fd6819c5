"""``python -m o2m``: the command-line interface (see :mod:`o2m.cli`)."""

from o2m.cli import main

raise SystemExit(main())
