"""Data files shipped with cbgo (see README.md here for their origin and licence)."""
