"""``python -m kgarment.cli``."""

import sys

from kgarment.cli import main

sys.exit(main())
