"""python/setup.py - builds the extension seamtex._seamtex for pip / setuptools.

The extension's sources are python/seamtex/*.c; it links libseamtex.a (client/, which
bundles protocol/ and util/). The archive is $SEAMTEX_LIB, else ../build/libseamtex.a of this
tree, which is built with `make -C .. build/libseamtex.a` first when it is missing. Built
with Debian's python3-dev and python3-setuptools:

    pip install --no-build-isolation ./python
"""

import os
import subprocess
from pathlib import Path

from setuptools import Extension, setup

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def libseamtex():
    lib = os.environ.get("SEAMTEX_LIB")
    if lib:
        return lib
    lib = ROOT / "build" / "libseamtex.a"
    if not lib.exists():
        subprocess.check_call(["make", "-C", str(ROOT), "build/libseamtex.a"])
    return str(lib)


ext = Extension(
    "seamtex._seamtex",
    sources=sorted(os.path.join("seamtex", p.name) for p in (HERE / "seamtex").glob("*.c")),
    depends=[os.path.join("seamtex", "pyseamtex.h")],
    include_dirs=[str(ROOT / "client"), str(ROOT / "protocol")],
    extra_compile_args=["-std=c11", "-D_GNU_SOURCE", "-Wall", "-Wextra", "-fvisibility=hidden"],
    extra_objects=[libseamtex()],
    libraries=["m", "pthread"],
)

setup(
    packages=["seamtex"],
    package_data={"seamtex": ["*.pyi", "py.typed"]},
    ext_modules=[ext],
)
