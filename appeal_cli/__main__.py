"""``python -m appeal_cli``: the ``appeal`` command."""

import sys

from appeal_cli import main

sys.exit(main())
