"""The long run of the CLI fuzz property (tests/test_cli_fuzz.py): thousands of mutated
PNG/JPEG/model files and random option values, then as many model files with changed
arrays (shapes, types, values) through load_model and synthesize.

    python scripts/fuzz_cli.py            # 3,000 cases of each (about 30 minutes on 2 cores)
    python scripts/fuzz_cli.py 200 --seed 7
    python scripts/fuzz_cli.py 300 --only arrays
    python scripts/fuzz_cli.py 100 --only stages   # --stages of every command, odd outputs (0.62)

Prints the failing case (Hypothesis shrinks it) and exits 1 if the property breaks.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "src"))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="?", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=None, help="Hypothesis seed (default: random)")
    parser.add_argument("--only", choices=["cli", "arrays", "stages"], default=None,
                        help="run one of the properties (stages: only when asked, a few seconds a case)")
    args = parser.parse_args()

    from collections import Counter

    from hypothesis import HealthCheck, given, seed, settings

    from test_cli_fuzz import check, check_model, check_stages, command, mutated_arrays, stages_command

    def run(strategy, prop):
        @settings(max_examples=args.cases, deadline=None, database=None,
                  suppress_health_check=list(HealthCheck))
        @given(strategy)
        def one(case):
            prop(case)

        if args.seed is not None:
            one = seed(args.seed)(one)
        one()

    if args.only in (None, "cli"):
        run(command(), lambda case: check(*case))
        print(f"CLI: {args.cases} cases, the property held", file=sys.stderr)
    if args.only in (None, "arrays"):
        outcomes = Counter()
        run(mutated_arrays(), lambda blob: outcomes.update([check_model(blob)]))
        print(f"model arrays: {args.cases} cases, the property held ({outcomes['loaded']} loaded and synthesized "
              f"a valid image, {outcomes['refused']} refused with one ModelFileError line; counts include "
              "Hypothesis' replays)", file=sys.stderr)
    if args.only == "stages":
        run(stages_command(), lambda case: check_stages(*case))
        print(f"--stages: {args.cases} cases, the property held", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
