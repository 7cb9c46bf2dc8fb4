"""python -m macrostate_mj.app.cli"""

from macrostate_mj.app.cli import main

main()
