"""python -m macrostate_mj: the same CLI as the `macrostate-mj` script."""

from macrostate_mj.app.cli import main

main()
