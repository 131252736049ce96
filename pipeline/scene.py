"""``python -m pipeline.scene``: runs :func:`pipeline.commands.scene.main`."""

import sys

from pipeline.commands.scene import main

if __name__ == "__main__":
    sys.exit(main())
