"""``python -m jaxmotion`` is the same as the ``jaxmotion`` command."""

from jaxmotion.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
