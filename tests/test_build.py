"""The Makefile's choice of PETSc (make config, make check-deps; nothing is built):
a PETSC_DIR/PETSC_ARCH PETSc gives its compilers, flags, rpath, HDF5 and METIS and
its own build directory; a missing piece is one sentence naming it."""
import os
import shutil
import subprocess

import pytest

from conftest import ROOT

pytestmark = pytest.mark.skipif(shutil.which("pkg-config") is None or subprocess.run(["pkg-config", "--exists", "petsc"]).returncode != 0,
                                reason="needs pkg-config's PETSc to copy a PETSc installation from")


def make(*args):
    env = {k: v for k, v in os.environ.items() if k not in ("PETSC_DIR", "PETSC_ARCH", "BUILD", "MAKEFLAGS", "MFLAGS", "MAKELEVEL")}
    proc = subprocess.run(["make", "--no-print-directory", *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    return proc.returncode, proc.stdout


def config(*args):
    rc, out = make("config", *args)
    assert rc == 0, out
    return dict(line.split(None, 1) if " " in line else (line, "") for line in out.splitlines())


def pkgvar(name):
    return subprocess.run(["pkg-config", f"--variable={name}", "petsc"], capture_output=True, text=True, check=True).stdout.strip()


@pytest.fixture
def petsc(tmp):
    """A PETSC_DIR/PETSC_ARCH tree copied from pkg-config's PETSc (its petsc.pc with a
    source build's rpath flag, petscconf.h and petscvariables), with METIS added."""
    home = tmp / "petsc" / "arch-test"
    (home / "lib" / "pkgconfig").mkdir(parents=True)
    (home / "lib" / "petsc" / "conf").mkdir(parents=True)
    (home / "include").mkdir()
    pc = open(os.path.join(pkgvar("libdir"), "pkgconfig", "petsc.pc")).read().splitlines()
    pc = [f"prefix={home}" if l.startswith("prefix=") else "ldflag_rpath=-Wl,-rpath," if l.startswith("ldflag_rpath=") else l for l in pc]
    (home / "lib" / "pkgconfig" / "petsc.pc").write_text("\n".join(pc) + "\n")
    conf = open(os.path.join(pkgvar("includedir"), "petscconf.h")).read()
    (home / "include" / "petscconf.h").write_text(conf + "#define PETSC_HAVE_METIS 1\n")
    variables = open(os.path.join(pkgvar("libdir"), "petsc", "conf", "petscvariables")).read()
    (home / "lib" / "petsc" / "conf" / "petscvariables").write_text(
        variables + "METIS_INCLUDE = -I/opt/metis64/include\nMETIS_LIB = -Wl,-rpath,/opt/metis64/lib -L/opt/metis64/lib -lmetis\n")
    return home


def test_petsc_dir_gives_flags_metis_and_its_own_build_directory(petsc):
    c = config(f"PETSC_DIR={petsc.parent}", "PETSC_ARCH=arch-test")
    assert c["BUILD"] == "build-" + str(petsc.resolve()).lstrip("/").replace("/", "_")
    assert f"-I{petsc}/include" in c["CPPFLAGS"] and "-I/opt/metis64/include" in c["CPPFLAGS"]
    assert f"-Wl,-rpath,{petsc}/lib" in c["LDFLAGS"].split()
    libs = c["LDLIBS"].split()
    assert "-L/opt/metis64/lib" in libs and libs.count("-lmetis") == 1
    # the default: pkg-config's PETSc in build/
    d = config()
    assert d["BUILD"] == "build" and "-lmetis" in d["LDLIBS"].split()


@pytest.mark.parametrize("arch, expect", [("", "PETSc builds found under PETSC_DIR: PETSC_ARCH=arch-test"),
                                          ("arch-none", "PETSc builds found under PETSC_DIR: PETSC_ARCH=arch-test")])
def test_missing_petsc_is_one_sentence_with_the_builds_found(petsc, arch, expect):
    rc, out = make("check-deps", f"PETSC_DIR={petsc.parent}", f"PETSC_ARCH={arch}")
    assert rc != 0 and out.count("\n") == 1 and out.startswith("drape: no PETSc at") and expect in out, out


def test_petsc_without_hdf5_is_one_sentence(petsc):
    conf = petsc / "include" / "petscconf.h"
    conf.write_text("".join(l for l in conf.read_text().splitlines(keepends=True) if "PETSC_HAVE_HDF5" not in l))
    rc, out = make("check-deps", f"PETSC_DIR={petsc.parent}", "PETSC_ARCH=arch-test")
    assert rc != 0 and out.count("\n") == 1 and "has no HDF5" in out and "--download-hdf5" in out, out
