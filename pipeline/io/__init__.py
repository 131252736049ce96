"""Files and processes: atomic JSON, provenance (versions, hashes)."""
