"""``python -m blindspot <stage> [hydra overrides]``: see :mod:`blindspot.cli`."""

from blindspot.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
