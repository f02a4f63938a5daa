"""Tests of lampfab.export: the STL, STEP and glTF files."""
