"""Trace readers: CSV/TXT, thesis GUI layouts, MATLAB .mat (EMPS), SINUMERIK servo-trace XML."""
