"""ctest's entry point for one test file: skips (exit 77) when Debian's Python packages for the
client are missing, else runs pytest on the file. usage: run_pytest.py TEST_FILE [PYTEST ARGS]"""

import sys

try:
    import grpc  # noqa: F401  python3-grpcio
    import google.protobuf  # noqa: F401  python3-protobuf
    import numpy  # noqa: F401  python3-numpy
    import pytest
except ImportError as error:
    print(f"skipped: {error.name} is missing for {sys.executable} (tools/setup.sh installs "
          "python3-grpcio python3-protobuf python3-numpy python3-pytest)")
    sys.exit(77)

# -p no:cacheprovider: no .pytest_cache written into the source tree.
sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", *sys.argv[1:]]))
