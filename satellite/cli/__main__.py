"""``python -m satellite.cli``: the ``isf-satellite`` command line."""

import sys

from satellite.cli import main

sys.exit(main())
