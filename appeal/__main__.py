import sys

from appeal.cli import main

sys.exit(main())
