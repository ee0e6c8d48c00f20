import sys

from mrfswarm.cli import main

sys.exit(main())
