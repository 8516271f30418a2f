"""``python -m jaxmotion`` is the same as the ``jaxmotion`` command."""

from jaxmotion.cli import run

if __name__ == "__main__":
    run()
