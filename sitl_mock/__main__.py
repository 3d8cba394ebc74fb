"""`python -m sitl_mock`: the same options as `mvo-gcs sitl`."""

from __future__ import annotations

import argparse
import sys

from .cli import add_arguments, run


def main() -> int:
    parser = argparse.ArgumentParser(
        prog="python -m sitl_mock",
        description="run simulated MAVLink vehicles (ArduCopter or PX4 flavour)",
    )
    add_arguments(parser)
    return run(parser.parse_args())


if __name__ == "__main__":
    sys.exit(main())
