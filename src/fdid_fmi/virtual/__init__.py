"""Virtual feed drive (placeholder, filled below)."""
