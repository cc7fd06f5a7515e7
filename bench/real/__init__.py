"""Real robot logs: DRIVE window tables, the real-data benchmark, the gap workflow on real logs."""
