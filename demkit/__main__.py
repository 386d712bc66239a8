"""``python -m demkit ...`` is the ``demkit`` command (see :mod:`demkit.cli`)."""
import sys

from .cli import main

sys.exit(main())
