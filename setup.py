"""Build the nbvkit._core extension with CMake (Ninja) from setuptools.

Works for `pip install .` and `pip install -e .` (run with --no-build-isolation --no-index). The
CMake build tree lives in build/cmake-<python tag> and is reused, so an editable re-install after
a C++ edit rebuilds only what changed.
"""
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        out = Path(self.get_ext_fullpath(ext.name)).resolve()
        out.parent.mkdir(parents=True, exist_ok=True)
        build_dir = ROOT / "build" / f"cmake-{sysconfig.get_config_var('SOABI') or 'py'}"
        build_dir.mkdir(parents=True, exist_ok=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 2))
        gen = ["-G", "Ninja"] if shutil.which("ninja") else []
        cfg = [
            "cmake",
            "-S",
            str(ROOT),
            "-B",
            str(build_dir),
            *gen,
            f"-DCMAKE_BUILD_TYPE={os.environ.get('NBV_BUILD_TYPE', 'Release')}",
            f"-DPython3_EXECUTABLE={sys.executable}",
            f"-DNBV_EXTENSION_DIR={out.parent}",
        ]
        if (
            "NBV_BUILD_TESTS" in os.environ
        ):  # otherwise keep what the build tree has (make test-cpp)
            cfg.append("-DNBV_BUILD_TESTS=" + os.environ["NBV_BUILD_TESTS"])
        subprocess.run(cfg, check=True)
        subprocess.run(
            ["cmake", "--build", str(build_dir), "--target", "_core", "-j", jobs], check=True
        )
        built = out.parent / out.name
        if not built.exists():
            raise RuntimeError(f"CMake did not produce {built}")


class BuildPyWithMeshes(build_py):
    """Ship the generated default airliner inside the package (nbvkit/data/airliner.obj)."""

    def run(self):
        super().run()
        src = ROOT / "meshes" / "airliner.obj"
        if src.exists() and not self.editable_mode:
            dst = Path(self.build_lib) / "nbvkit" / "data" / "airliner.obj"
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst)


setup(
    ext_modules=[CMakeExtension("nbvkit._core")],
    cmdclass={"build_ext": CMakeBuild, "build_py": BuildPyWithMeshes},
)
