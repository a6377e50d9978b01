"""Run every benchmark (``make bench``): first the A/B table of this checkout against the previous
release (benchmarks/ab.py: solver shares, goals, ratios), then each benchmarks/bench_*.py, whose
main() prints its figures and the ratios against the papers' numbers.
``python benchmarks/run_all.py srf los`` runs a subset of bench_*.py and skips the A/B table;
``python benchmarks/run_all.py ab`` runs only the A/B table."""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

HERE = Path(__file__).parent


def main(selected: list[str]) -> int:
    failures = 0
    if not selected or "ab" in selected:
        print("=== A/B against the previous release " + "=" * 34, flush=True)
        t0 = time.perf_counter()
        sys.path.insert(0, str(HERE))
        import ab

        failures += ab.main([]) != 0
        print(f"[ab: {time.perf_counter() - t0:.1f} s]", flush=True)
    for path in sorted(HERE.glob("bench_*.py")):
        name = path.stem[len("bench_"):]
        if selected and name not in selected:
            continue
        print(f"\n=== {name} " + "=" * (60 - len(name)), flush=True)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        t0 = time.perf_counter()
        argv, sys.argv = sys.argv, [str(path)]  # each benchmark parses its own (default) options
        try:
            spec.loader.exec_module(module)
            module.main()
        except Exception as exc:  # one broken benchmark must not hide the others
            failures += 1
            print(f"benchmark {name} failed: {exc!r}")
        finally:
            sys.argv = argv
        print(f"[{name}: {time.perf_counter() - t0:.1f} s]", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
