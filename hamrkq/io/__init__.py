"""Output files: directory policy, atomic writes, JSON and NPZ."""
