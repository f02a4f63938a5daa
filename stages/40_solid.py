#!/usr/bin/env python3
"""Stage 40: solid.  See `lampfab solid --help`; the work lives in lampfab.pipeline.solid."""
import sys

from lampfab.cli import main

sys.exit(main(stage="solid"))
