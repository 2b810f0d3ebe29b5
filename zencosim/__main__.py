"""``python -m zencosim``: the command line."""
import sys

from zencosim.cli.main import main

sys.exit(main())
