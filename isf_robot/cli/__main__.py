"""``python -m isf_robot.cli``: the same as ``isf-robot``."""

import sys

from isf_robot.cli import main

sys.exit(main())
