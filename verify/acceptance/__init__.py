"""The acceptance verifier's library, in data-flow order: which obstacles (:mod:`.cases`), what is
measured on each (:mod:`.metrics` into the typed :mod:`.results`), running many
(:mod:`.run`), their :mod:`.summary`, the printed :mod:`.report` and the :mod:`.plots`; and
certify-or-repair over many obstacles (:mod:`.online`). The CLIs ``verify.sweep`` and
``verify.online_sweep`` only parse and call these."""
