"""``python -m ros2_pip_cli ...``: what the venv's ``ros2`` launcher runs."""

import sys

from ._main import main

sys.exit(main())
