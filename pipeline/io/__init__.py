"""Files and processes: atomic JSON, provenance (versions, hashes), one process-pool map."""
