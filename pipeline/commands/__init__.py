"""The command lines of ``pipeline``: each module declares its options, calls the library and
prints; ``python -m pipeline.build``, ``python -m pipeline.generate``, ``python -m pipeline.regress``
and ``python -m pipeline.certify_range`` run them."""
