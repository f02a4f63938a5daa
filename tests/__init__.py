"""The tests, laid out like lampfab: one folder per package, flat modules at the top."""
