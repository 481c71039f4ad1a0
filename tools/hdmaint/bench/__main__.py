"""python -m hdmaint.bench: tools/bench, with hdsense's exit statuses and
one-line errors (hdtools.cli.run)."""
import sys

from hdtools.cli import run

from .cli import parser

sys.exit(run(parser, None, "tools/bench"))
