#!/usr/bin/env python3
"""Stage 70: verify.  See `lampfab verify --help`; the work lives in lampfab.pipeline.verify."""
import sys

from lampfab.cli import main

sys.exit(main(stage="verify"))
