"""``python -m locoman.grid <scenario> <figure> [hydra overrides ...]``: see
:mod:`locoman.grid.launch`."""

import sys

from locoman.grid.launch import main

sys.exit(main(sys.argv[1:]))
