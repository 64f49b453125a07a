import sys

from femgran.cli import main

sys.exit(main())
