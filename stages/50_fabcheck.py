#!/usr/bin/env python3
"""Stage 50: fabcheck.  See `lampfab fabcheck --help`; the work lives in lampfab.pipeline.fabcheck."""
import sys

from lampfab.cli import main

sys.exit(main(stage="fabcheck"))
