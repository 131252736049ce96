"""``python -m pipeline.regress``: runs :func:`pipeline.commands.regress.main`."""

import sys

from pipeline.commands.regress import main

if __name__ == "__main__":
    sys.exit(main())
