"""Speed of the detection chain on one MMWCAS frame: `python benchmarks/bench_dsp.py [--threads 1]`.

The same command as `python -m blindspot.bench.dsp` (DESIGN.md's interface), kept here beside the
other benchmarks.
"""

import sys

from blindspot.bench.dsp import main

if __name__ == "__main__":
    sys.exit(main())
