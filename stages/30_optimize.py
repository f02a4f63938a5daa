#!/usr/bin/env python3
"""Stage 30: optimize.  See `lampfab optimize --help`; the work lives in lampfab.pipeline.optimize."""
import sys

from lampfab.cli import main

sys.exit(main(stage="optimize"))
