import sys

from .cli import main
from .sweeps.lifeline import die_with_parent

die_with_parent()  # a sweep member's `ipsph run`: dies with its worker (no-op otherwise)
sys.exit(main())
