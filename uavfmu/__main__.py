"""``python -m uavfmu``: the same command line as the installed ``uavfmu`` script."""

import sys

from uavfmu.cli import main

sys.exit(main())
