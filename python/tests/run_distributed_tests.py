"""ctest entry for test_distributed.py: exit 77 (shown as skipped) when
dask/distributed, numpy or pytest is missing, else pytest's exit status."""
import os
import sys


def main():
    try:
        import distributed  # noqa: F401
        import numpy  # noqa: F401
        import pytest
    except ImportError as e:
        print("SKIP: %s (Debian: apt-get install python3-distributed python3-pytest python3-numpy)" % e)
        return 77
    here = os.path.dirname(os.path.abspath(__file__))
    return pytest.main(["-q", "-p", "no:cacheprovider", os.path.join(here, "test_distributed.py")] + sys.argv[1:])


# Dask's worker processes are spawned and import this file as __mp_main__:
# they must not run the tests again.
if __name__ == "__main__":
    sys.exit(main())
