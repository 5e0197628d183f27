"""``python -m suds_ros.cli``: the ``suds`` command."""

import sys

from suds_ros.cli.main import main

sys.exit(main())
