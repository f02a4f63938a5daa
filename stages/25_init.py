#!/usr/bin/env python3
"""Stage 25: init.  See `lampfab init --help`; the work lives in lampfab.pipeline.init."""
import sys

from lampfab.cli import main

sys.exit(main(stage="init"))
