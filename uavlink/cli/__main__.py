"""``python -m uavlink.cli``: the ``uavlink`` command."""

import sys

from uavlink.cli import main

sys.exit(main())
