"""``python -m uavlink``: the ``uavlink`` command (as ``python -m uavlink.cli``)."""

import sys

from uavlink.cli import main

sys.exit(main())
