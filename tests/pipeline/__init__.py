"""Tests of lampfab.pipeline: the stages, end to end through make and the command line."""
