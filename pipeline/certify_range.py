"""``python -m pipeline.certify_range``: runs :func:`pipeline.commands.certify_range.main`."""

import sys

from pipeline.commands.certify_range import main

if __name__ == "__main__":
    sys.exit(main())
