"""``python -m mrfswarm``: the ``mrfswarm`` command, where its console script is not on the PATH."""

import sys

from mrfswarm.cli import main

if __name__ == "__main__":
    sys.exit(main())
