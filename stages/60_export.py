#!/usr/bin/env python3
"""Stage 60: export.  See `lampfab export --help`; the work lives in lampfab.pipeline.export."""
import sys

from lampfab.cli import main

sys.exit(main(stage="export"))
