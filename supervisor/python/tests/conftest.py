"""What the tests share: the harvemu binary, for the tests that run it beside the package."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).parents[3]


@pytest.fixture(scope="session")
def harvemu_bin():
    """The harvemu binary: HARVEMU_BIN when set; else the workspace's build (under
    CARGO_TARGET_DIR or target/: debug, then the optimised profiles); else `harvemu` on PATH.
    None of these is a failure that names HARVEMU_BIN: the tests that need it never skip."""
    named = os.environ.get("HARVEMU_BIN")
    if named:
        assert pathlib.Path(named).is_file(), f"HARVEMU_BIN={named} is no file"
        return named
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    if not target.is_absolute():
        target = ROOT / target
    for profile in ("debug", "vm", "release"):
        candidate = target / profile / "harvemu"
        if candidate.is_file():
            return str(candidate)
    on_path = shutil.which("harvemu")
    assert on_path, (f"no harvemu binary under {target} (debug, vm, release) nor on PATH: build "
                     f"it (cargo build) or set HARVEMU_BIN to its path")
    return on_path
