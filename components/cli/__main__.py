"""``python -m components.cli``: the calbench command line (the campaign's workers use it)."""
import sys

from components.cli import main

sys.exit(main())
