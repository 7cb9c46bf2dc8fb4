"""python -m macrostate_mj: the same CLI as the `macrostate-mj` script."""

from macrostate_mj.app.cli import main

if __name__ == "__main__":      # importing it (a tool's scan, a spawned worker) runs nothing
    main()
