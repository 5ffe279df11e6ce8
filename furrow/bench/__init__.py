"""Speed-against-error benchmarks, one module per benchmark (``furrow bench NAME``).

Every module has ``main(argv) -> int``; ``furrow.cmd_bench`` finds them with :mod:`pkgutil`, so
they run from an installed package as well as from a source checkout
(``python -m furrow.bench.NAME`` works too).
"""

from pathlib import Path

#: Default output root, relative to the working directory (``make bench`` runs from the repository
#: root, so results land in ``out/bench/NAME``); every benchmark takes ``-o DIR`` instead.
OUT_ROOT = Path("out")
