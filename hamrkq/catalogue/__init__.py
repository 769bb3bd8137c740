"""The problem catalogue: the TOML file format, :class:`Problem`, exact solutions."""
