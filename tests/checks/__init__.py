"""Tests of lampfab.checks: the fabrication checks."""
