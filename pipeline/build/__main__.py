"""``python -m pipeline.build``: the command line of :mod:`pipeline.commands.build`."""

import sys

from pipeline.commands.build import main

sys.exit(main())
