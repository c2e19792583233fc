"""`python -m longslam`: the `longslam` command."""

import sys

from longslam.cli.main import main

sys.exit(main())
