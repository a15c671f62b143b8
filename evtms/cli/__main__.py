"""``python -m evtms.cli``: the command line."""

from evtms.cli import main

if __name__ == "__main__":  # pragma: no cover
    main()
