"""Identification methods (thesis ch. 3, 4, 5)."""
