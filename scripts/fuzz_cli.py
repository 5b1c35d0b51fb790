"""The long run of the CLI fuzz property (tests/test_cli_fuzz.py): thousands of mutated
PNG/JPEG/model files and random option values.

    python scripts/fuzz_cli.py            # 3,000 cases (about 20 minutes on 2 cores)
    python scripts/fuzz_cli.py 200 --seed 7

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
    args = parser.parse_args()

    from hypothesis import HealthCheck, given, seed, settings

    from test_cli_fuzz import check, command

    @settings(max_examples=args.cases, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(command())
    def run(case):
        check(*case)

    if args.seed is not None:
        run = seed(args.seed)(run)
    run()
    print(f"{args.cases} cases: the property held", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
