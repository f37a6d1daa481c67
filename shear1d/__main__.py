"""``python -m shear1d``: the shear1d command line (see :mod:`shear1d.cli`)."""

import sys

from .cli import main

sys.exit(main())
