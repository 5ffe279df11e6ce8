import sys

from furrow.cli import main

sys.exit(main())
