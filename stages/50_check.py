#!/usr/bin/env python3
"""Stage 50: check.  See `lampfab check --help`; the work lives in lampfab.pipeline.check."""
import sys

from lampfab.cli import main

sys.exit(main(stage="check"))
