"""`python -m longslam.cli`: the `longslam` command."""

import sys

from longslam.cli.main import main

sys.exit(main())
