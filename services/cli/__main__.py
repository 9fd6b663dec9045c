"""`python -m services.cli` runs the tidelink command line."""

import sys

from services.cli import main

sys.exit(main())
