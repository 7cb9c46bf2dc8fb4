"""python -m macrostate_mj.cli"""

from macrostate_mj.cli import main

main()
