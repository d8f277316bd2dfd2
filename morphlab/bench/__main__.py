"""``python -m morphlab.bench``: see :mod:`morphlab.bench.suite`."""

import sys

from .suite import main

sys.exit(main())
