"""The online stage: the generator (coefficients + (L, W) -> trajectory) and certify-or-repair."""
