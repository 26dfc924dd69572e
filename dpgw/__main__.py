import sys

from dpgw.cli import main

if __name__ == "__main__":  # (not when a spawned child imports it)
    sys.exit(main())
