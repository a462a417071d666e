"""Builds qota's Python extension with CMake (python/CMakeLists.txt) for pip."""
import os
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        root = Path(__file__).resolve().parent
        out = Path(self.get_ext_fullpath(ext.name)).resolve().parent
        build = Path(os.environ.get("QOTA_PYTHON_BUILD_DIR", root / "build-python"))
        cache = build / "CMakeCache.txt"
        own = [f"-DPython_EXECUTABLE={sys.executable}", f"-DCMAKE_LIBRARY_OUTPUT_DIRECTORY={out}"]
        if cache.exists() and "QOTA_BUILD_PYTHON:BOOL=ON" in cache.read_text():
            options = own  # a build made with the extension (scripts/test.sh's): its options kept
        else:
            options = ["-DCMAKE_BUILD_TYPE=Release", "-DQOTA_BUILD_PYTHON=ON", "-DQOTA_BUILD_TESTS=OFF",
                       "-DQOTA_BUILD_BENCH=OFF", "-DQOTA_BUILD_EXAMPLES=OFF", "-DQOTA_BUILD_TOOLS=ON",
                       "-DQOTA_INSTALL=OFF", "-DCMAKE_POSITION_INDEPENDENT_CODE=ON"] + own
        subprocess.run(["cmake", "-S", str(root), "-B", str(build)] + options, check=True)
        subprocess.run(["cmake", "--build", str(build), "--target", "qota_python", "-j",
                        os.environ.get("QOTA_JOBS", "2")], check=True)


setup(ext_modules=[CMakeExtension("qota._qota")], cmdclass={"build_ext": CMakeBuild})
