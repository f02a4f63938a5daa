#!/usr/bin/env python3
"""Stage 10: prepare.  See `lampfab prepare --help`; the work lives in lampfab.pipeline.prepare."""
import sys

from lampfab.cli import main

sys.exit(main(stage="prepare"))
