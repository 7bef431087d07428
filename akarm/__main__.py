import sys

from akarm.cli import main

sys.exit(main())
