"""``python -m pipeline.generate``: runs :func:`pipeline.commands.generate.main`.

An entry point for ``-m`` only. ``pipeline.generate`` is the function
:func:`pipeline.online.generator.generate`; importing a module of that name would rebind it, so
this module refuses to be imported (the command's code is :mod:`pipeline.commands.generate`).
"""

import sys

if __name__ != "__main__":
    raise ImportError(
        "pipeline.generate is the generator function; run the command line as python -m pipeline.generate, "
        "or import pipeline.commands.generate"
    )

from pipeline.commands.generate import main

sys.exit(main())
