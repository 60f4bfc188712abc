"""``python -m splatconv``: the same command as ``splatconv``."""

from .cli import main

main(prog_name="splatconv")
