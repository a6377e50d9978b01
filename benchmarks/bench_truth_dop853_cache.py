"""Benchmark/probe: does numba's on-disk cache (cache=True) keep working when one integrator loop
serves several right-hand sides? (issue 31 item 5, the DOP853 loop of kernels.py / kernels_full.py).

Three ways to write a loop once for two right-hand sides, each in a throw-away module compiled in a
fresh cache folder, then imported again by a second process: (closure) a factory returning an
@njit(cache=True) closure over the jitted RHS; (argument) the RHS passed as a first-class function
argument; (bound copy) a copy of the loop's code whose globals bind the RHS, with its own name (built
and measured bit-identical on 2026-11-28, but 1-9 % slower than the two hand-written copies on idle
cores, so kernels.py / kernels_full.py keep their copies). Prints, for the second process, the cache hits and
misses of the loop and the number of cache data files after both processes. A miss in the second
process means a recompilation in every process (numba 0.68: a closure's or a function argument's
cache key holds the pickled dispatcher, whose uuid4 is new in every process).
Run: ``.venv/bin/python benchmarks/bench_truth_dop853_cache.py`` (~1 min: 6 numba processes).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap

RHS = '''
import types
import numpy as np
from numba import njit

@njit(cache=True)
def rhs_a(t, y, out):
    for i in range(y.size):
        out[i] = -y[i] + 0.1 * t

@njit(cache=True)
def rhs_b(t, y, out):
    for i in range(y.size):
        out[i] = -2.0 * y[i] * y[i]
'''
LOOP = '''
    y = y0.copy()
    f = np.empty(y.size)
    t = 0.0
    for k in range(n):
        {call}(t, y, f)
        for i in range(y.size):
            y[i] += h * f[i]
        t += h
    return y
'''
MODULES = {
    "closure": RHS + "\ndef make(rhs):\n    @njit(cache=True)\n    def loop(y0, h, n):" + textwrap.indent(LOOP.format(call="rhs"), "    ")
    + "    return loop\n\nloop_a = make(rhs_a)\nloop_b = make(rhs_b)\n",
    "argument": RHS + "\n@njit(cache=True)\ndef loop(rhs, y0, h, n):" + LOOP.format(call="rhs")
    + "\ndef loop_a(y0, h, n):\n    return loop(rhs_a, y0, h, n)\n\ndef loop_b(y0, h, n):\n    return loop(rhs_b, y0, h, n)\n",
    "bound copy": RHS + "\ndef _loop(y0, h, n):" + LOOP.format(call="RHS") + '''
def bind(name, rhs):
    f = types.FunctionType(_loop.__code__, dict(_loop.__globals__, RHS=rhs), name)
    f.__qualname__ = name
    return njit(cache=True)(f)

loop_a = bind("loop_a", rhs_a)
loop_b = bind("loop_b", rhs_b)
''',
}
RUN = '''
import json, numpy as np, probe
a = probe.loop_a(np.ones(3), 0.01, 100)
b = probe.loop_b(np.ones(3), 0.01, 100)
d = probe.loop if hasattr(probe, "loop") else probe.loop_a
print(json.dumps({"hits": sum(d.stats.cache_hits.values()), "misses": sum(d.stats.cache_misses.values()),
                  "a": float(a[0]), "b": float(b[0])}))
'''


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.1f}")
    for label, source in MODULES.items():
        with tempfile.TemporaryDirectory() as tmp:
            with open(os.path.join(tmp, "probe.py"), "w") as f:
                f.write(source)
            env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "cache"), PYTHONPATH=tmp)
            runs = [json.loads(subprocess.run([sys.executable, "-c", RUN], env=env, cwd=tmp, capture_output=True,
                                              text=True, check=True).stdout.strip().splitlines()[-1]) for _ in range(2)]  # fmt: skip
            files = sum(name.endswith(".nbc") and "loop" in name for _, _, names in os.walk(env["NUMBA_CACHE_DIR"])
                        for name in names)  # fmt: skip
            second = runs[1]
            print(f"  {label:<11} second process: loop cache hits {second['hits']}, misses {second['misses']}; "
                  f"loop cache files after two processes: {files}; results a {second['a']:.6f}, b {second['b']:.6f} "
                  f"(first process a {runs[0]['a']:.6f}, b {runs[0]['b']:.6f})")


if __name__ == "__main__":
    main()
