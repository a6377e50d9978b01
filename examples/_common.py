"""Shared by the examples: the --quick flag (a shortened run for the test suite)."""

import sys

QUICK = "--quick" in sys.argv[1:]
