#!/usr/bin/env python3
"""Stage 20: plan.  See `lampfab plan --help`; the work lives in lampfab.pipeline.plan."""
import sys

from lampfab.cli import main

sys.exit(main(stage="plan"))
