import sys

from sc_rt.cli.main import main

sys.exit(main())
