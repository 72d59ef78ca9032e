"""``python -m sinslab``: the same command line as the ``sinslab`` script."""
from sinslab.cli import main

if __name__ == "__main__":
    main()
