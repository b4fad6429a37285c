"""Point the ROS wheels' CMake exports at this venv's Python and NumPy include folders.

The ros-* wheels were built under /opt/python/cp311-cp311 and their
``*__rosidl_generator_pyExport.cmake`` files still name that prefix's include folders, so CMake
rejects any interface package that depends on their messages ("includes non-existent path").
Rewriting is idempotent: a second run finds nothing left to change.
"""

import sys
import sysconfig
from pathlib import Path

import numpy

BUILDER_PREFIX = "/opt/python/cp311-cp311"
REWRITES = {
    f"{BUILDER_PREFIX}/lib/python3.11/site-packages/numpy/_core/include": numpy.get_include(),
    f"{BUILDER_PREFIX}/include/python3.11": sysconfig.get_paths()["include"],
}


def main() -> int:
    changed = 0
    for path in Path(sys.prefix, "share").glob("*/cmake/*.cmake"):
        text = path.read_text()
        if BUILDER_PREFIX not in text:
            continue
        new = text
        for old, replacement in REWRITES.items():
            new = new.replace(old, replacement)
        if new != text:
            path.write_text(new)
            changed += 1
    print(f"fix_wheel_cmake_paths: rewrote {changed} file(s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
