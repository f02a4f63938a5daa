"""Tests of lampfab.panel: the source's prior-work scene."""
