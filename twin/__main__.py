"""``python -m twin``: the command line, as the ``twin`` script runs it (:func:`twin.cli.main`)."""

import sys

from twin.cli import main

if __name__ == "__main__":
    sys.exit(main())
