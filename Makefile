# drape: build, run and test.
#   make run    set up what is missing, build, simulate runs/hang.opts, write HDF5 and a PNG
#   make test   set up what is missing, build, run every test
#   make check  build and run every test with what is installed (installs nothing)
#   make all    build only (WERROR=1: a warning in drape's code stops it)
#   make format apply .clang-format; make format-check: fail if that would change a file
# PETSc: the one PETSC_DIR (and PETSC_ARCH) names, from the environment or the
# command line (a cluster's PETSc module); without PETSC_DIR, pkg-config's `petsc`
# (Debian: petsc-dev). As PETSc's share/petsc/Makefile.user does, its petsc.pc gives
# the compilers (its mpicc, mpicxx), the include and link flags and the rpath;
# drape's own CFLAGS replace PETSc's optimisation flags. MPI (when PETSc's compilers
# are not MPI wrappers) and HDF5, which drape calls directly too, are PETSc's, from
# its petscvariables; METIS is PETSc's when PETSc has it (petscconf.h), else the
# system's -lmetis; -lgmp -lmpfr only if CGAL uses them.
# Out of tree, with generated dependencies, in $(BUILD): build/ for the default
# PETSc, build-<PETSc's path with / as _> for another, so builds never mix objects.

VENV    ?= .venv
NP      ?= 2
OUT     ?= out
CFLAGS  ?= -O3 -g -fno-math-errno
CXXFLAGS ?= -O3 -g
TESTS   ?= tests
REQUIREMENTS ?= scripts/requirements.txt
# NATIVE=1 adds -march=native (faster on the build machine, may not run on others)
ifeq ($(NATIVE),1)
CFLAGS   += -march=native
CXXFLAGS += -march=native
endif

DEBIAN_PACKAGES := petsc-dev libmetis-dev libhdf5-openmpi-dev libcgal-dev
ifdef PETSC_DIR
PETSC_HOME := $(patsubst %/,%,$(PETSC_DIR)/$(PETSC_ARCH))
PETSC_PC   := $(firstword $(wildcard $(PETSC_HOME)/lib/pkgconfig/PETSc.pc $(PETSC_HOME)/lib/pkgconfig/petsc.pc))
PETSC_NAME := PETSc at PETSC_DIR=$(PETSC_DIR) PETSC_ARCH=$(PETSC_ARCH)
PETSC_FOUND := $(strip $(if $(wildcard $(PETSC_DIR)/lib/pkgconfig/*.pc),PETSC_ARCH='') $(addprefix PETSC_ARCH=,$(sort \
                 $(patsubst $(PETSC_DIR)/%/lib/pkgconfig/,%,$(dir $(wildcard $(PETSC_DIR)/*/lib/pkgconfig/PETSc.pc $(PETSC_DIR)/*/lib/pkgconfig/petsc.pc))))))
PETSC_MISSING := drape: no PETSc at PETSC_DIR=$(PETSC_DIR) PETSC_ARCH=$(PETSC_ARCH) (no $(PETSC_HOME)/lib/pkgconfig/petsc.pc); \
  $(if $(PETSC_FOUND),PETSc builds found under PETSC_DIR: $(PETSC_FOUND),PETSC_DIR must name a configured PETSc and PETSC_ARCH its build (empty for a --prefix install))
BUILD ?= build-$(subst /,_,$(patsubst /%,%,$(or $(realpath $(PETSC_HOME)),$(abspath $(PETSC_HOME)))))
else
PETSC_PC   := $(if $(shell pkg-config --exists petsc 2>/dev/null && echo y),petsc)
PETSC_NAME := pkg-config's PETSc
PETSC_MISSING := drape: PETSc not found (pkg-config knows no petsc); set PETSC_DIR and PETSC_ARCH to a PETSc build, or run 'make deps' (Debian: apt-get install $(DEBIAN_PACKAGES))
BUILD ?= build
endif

# PETSc's pkg-config data, configuration header and make variables
pc = $(if $(PETSC_PC),$(shell pkg-config $(1) $(PETSC_PC) 2>/dev/null))
PETSC_INCDIR := $(call pc,--variable=includedir)
PETSC_LIBDIR := $(call pc,--variable=libdir)
petsc_conf = $(if $(PETSC_INCDIR),$(shell grep -qs '^#define PETSC_$(1) 1' $(PETSC_INCDIR)/petscconf.h && echo 1))
petsc_var  = $(if $(PETSC_LIBDIR),$(shell sed -n 's/^$(1) *= *//p' $(PETSC_LIBDIR)/petsc/conf/petscvariables 2>/dev/null))

CC  := $(or $(call pc,--variable=ccompiler),mpicc)
CXX := $(or $(call pc,--variable=cxxcompiler),mpicxx)
PETSC_HDF5  := $(call petsc_conf,HAVE_HDF5)
PETSC_METIS := $(call petsc_conf,HAVE_METIS)
# a static PETSc (no PETSC_USE_SHARED_LIBRARIES) also needs the libraries it uses
PETSC_STATIC := $(if $(PETSC_PC),$(if $(call petsc_conf,USE_SHARED_LIBRARIES),,--static))
PETSC_RPATH  := $(call pc,--variable=ldflag_rpath)

DRAPE_CPPFLAGS := -Iinclude $(call pc,--cflags) $(call petsc_var,MPI_INCLUDE) $(call petsc_var,HDF5_INCLUDE) $(if $(PETSC_METIS),$(call petsc_var,METIS_INCLUDE))
DRAPE_CFLAGS   := -std=c11 -Wall -Wextra -Wno-unused-parameter -MMD -MP
DRAPE_CXXFLAGS := -std=c++17 -frounding-math -Wall -Wextra -Wno-unused-parameter -MMD -MP
# WERROR=1 (CI): a warning in drape's own code (its C, C++ and headers) stops the build
ifeq ($(WERROR),1)
DRAPE_CFLAGS   += -Werror
DRAPE_CXXFLAGS += -Werror
endif
DRAPE_LDFLAGS  := $(call pc,--libs-only-L --libs-only-other $(PETSC_STATIC)) \
                  $(if $(PETSC_RPATH),$(patsubst -L%,$(PETSC_RPATH)%,$(call pc,--libs-only-L $(PETSC_STATIC))))
DRAPE_LDLIBS   := $(call pc,--libs-only-l $(PETSC_STATIC)) $(call petsc_var,HDF5_LIB) $(if $(PETSC_METIS),$(call petsc_var,METIS_LIB),-lmetis) \
                  $(call petsc_var,MPI_LIB)
# CGAL (header-only) uses GMP and MPFR when their headers are installed; asked once, at the first link
CGAL_LIBS = $(eval CGAL_LIBS := $(shell printf '\#include <CGAL/config.h>\n\#if defined(CGAL_USE_GMP) && defined(CGAL_USE_MPFR)\n-lgmp -lmpfr\n\#endif\n' | \
              $(CXX) $(DRAPE_CPPFLAGS) -x c++ -E - 2>/dev/null | grep '^-l'))$(CGAL_LIBS)
LDLIBS = $(DRAPE_LDLIBS) $(CGAL_LIBS) -lm

LIB_C   := $(filter-out src/main.c,$(wildcard src/*.c src/*/*.c))
LIB_CXX := $(wildcard src/*/*.cxx)
OBJ     := $(LIB_C:%.c=$(BUILD)/%.o) $(LIB_CXX:%.cxx=$(BUILD)/%.o)
LINK    := $(if $(LIB_CXX),$(CXX),$(CC))
UNIT    := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(wildcard tests/unit/*.c))

MPIEXEC ?= mpiexec $(if $(filter 0,$(shell id -u)),--allow-run-as-root) --oversubscribe
# Python for make check: the virtual environment of make venv if there is one
PYTHON  ?= $(if $(wildcard $(VENV)/bin/python),$(VENV)/bin/python,python3)
PYTHON_MODULES := numpy h5py matplotlib PIL pytest

.PHONY: all deps venv run test check check-deps check-python config bench format format-check clean
# a compiler or archiver that fails (or is stopped by make) leaves no half-written object
.DELETE_ON_ERROR:
all: $(BUILD)/drape $(UNIT)

# what the build takes from PETSc and the system
config:
	@echo "PETSc    $(PETSC_NAME): $(or $(PETSC_PC),not found)"
	@echo "BUILD    $(BUILD)"
	@echo "CC       $(CC)"
	@echo "CXX      $(CXX)"
	@echo "CPPFLAGS $(DRAPE_CPPFLAGS)"
	@echo "LDFLAGS  $(DRAPE_LDFLAGS)"
	@echo "LDLIBS   $(LDLIBS)"

# What the build needs, in order; the first missing piece stops it with one sentence.
check-deps:
	@command -v pkg-config >/dev/null || { echo "drape: pkg-config is missing; install it (Debian: apt-get install pkg-config)"; exit 1; }
	@test -n "$(PETSC_PC)" || { echo "$(PETSC_MISSING)"; exit 1; }
	@command -v $(firstword $(CC)) >/dev/null || { echo "drape: the C compiler $(firstword $(CC)) (PETSc's, from its petsc.pc, unless CC=... names another) is not on PATH; load the MPI that PETSc was built with"; exit 1; }
	@command -v $(firstword $(CXX)) >/dev/null || { echo "drape: the C++ compiler $(firstword $(CXX)) (PETSc's, mpicxx if PETSc names none, or CXX=...) is not on PATH; drape's CGAL part needs one: load the MPI that PETSc was built with or name one with CXX=..."; exit 1; }
	@test -n "$(PETSC_HDF5)" || { echo "drape: $(PETSC_NAME) has no HDF5 (no PETSC_HAVE_HDF5 in $(PETSC_INCDIR)/petscconf.h), and drape writes through PetscViewerHDF5; configure PETSc with --download-hdf5 or --with-hdf5-dir=DIR"; exit 1; }
	@printf '#include <metis.h>\n' | $(CC) $(DRAPE_CPPFLAGS) -E - >/dev/null 2>&1 || { echo "drape: METIS not found (no metis.h; $(PETSC_NAME) has no METIS); install it (Debian: apt-get install libmetis-dev) or configure PETSc with --download-metis"; exit 1; }
	@printf '#include <CGAL/AABB_tree.h>\n' | $(CXX) $(DRAPE_CPPFLAGS) -x c++ -E - >/dev/null 2>&1 || { echo "drape: CGAL not found (no CGAL/AABB_tree.h, or Boost missing); install it (Debian: apt-get install libcgal-dev)"; exit 1; }

# the C unit tests reach the private headers they test by their folder under src/
# (#include <cloth/kernels.h>), not by a relative path
$(BUILD)/tests/unit/%.o: DRAPE_CPPFLAGS += -Isrc

# the lattice force kernel: no floating-point traps to preserve, so GCC may compute
# both sides of a select and vectorise the loops; and multiply-adds contracted (ISO C
# modes default to -ffp-contract=off), so that its AVX2 and AVX-512 versions use
# fused multiply-adds: the same motion to round-off (src/cloth/lattice.c), symplectic
# Euler 8-11 % less CPU time on a Zen 3 (BENCHMARKS.md)
$(BUILD)/src/cloth/lattice.o: DRAPE_CFLAGS += -fno-trapping-math -ffp-contract=fast
# the same for the angle elements' Hessians, formed in lanes (src/cloth/kernels.h),
# whose instruction-set versions must give the same bits: no fused multiply-adds
$(BUILD)/src/cloth/forces.o: DRAPE_CFLAGS += -fno-trapping-math -ffp-contract=off
# the near list's distances, in lanes (src/selfcontact/nearlanes.c): the same bits
# as the scalar distance in every instruction-set version
$(BUILD)/src/selfcontact/nearlanes.o: DRAPE_CFLAGS += -fno-trapping-math -ffp-contract=off

$(BUILD)/%.o: %.c | check-deps
	@mkdir -p $(dir $@)
	$(CC) $(DRAPE_CPPFLAGS) $(DRAPE_CFLAGS) $(CFLAGS) -c $< -o $@

$(BUILD)/%.o: %.cxx | check-deps
	@mkdir -p $(dir $@)
	$(CXX) $(DRAPE_CPPFLAGS) $(DRAPE_CXXFLAGS) $(CXXFLAGS) -c $< -o $@

$(BUILD)/libdrape.a: $(OBJ)
	ar rcs $@ $^

$(BUILD)/drape: $(BUILD)/src/main.o $(BUILD)/libdrape.a
	$(LINK) $(CFLAGS) $(DRAPE_LDFLAGS) -o $@ $^ $(LDLIBS)

$(BUILD)/tests/%: $(BUILD)/tests/unit/%.o $(BUILD)/libdrape.a
	@mkdir -p $(dir $@)
	$(LINK) $(CFLAGS) $(DRAPE_LDFLAGS) -o $@ $^ $(LDLIBS)

# Debian packages; with PETSC_DIR given, all but PETSc's own
deps:
	@bash scripts/install-deps.sh $(if $(PETSC_DIR),--without-petsc)

# The virtual environment is checked at every make venv (pip, the pinned packages and
# their files: under a second, no network) and made again when an interrupted
# earlier run left it incomplete, so no stamp file can vouch for a broken one.
venv:
	@bash scripts/install-deps.sh --python $(VENV) $(REQUIREMENTS)

check-python:
	@command -v $(PYTHON) >/dev/null || { echo "drape: the tests need Python 3 ($(PYTHON) not found); install it (Debian: apt-get install python3) or name it with PYTHON=..."; exit 1; }
	@$(PYTHON) -c 'import importlib.util, sys; m = [n for n in sys.argv[1:] if importlib.util.find_spec(n) is None]; \
	  m and print("drape: the tests need the Python packages " + ", ".join(m) + " (not found by $(PYTHON)); run make venv (pip installs scripts/requirements.txt into $(VENV)) or install them (Debian: apt-get install " + " ".join("python3-" + n.lower() for n in m) + ")"); \
	  sys.exit(1 if m else 0)' $(PYTHON_MODULES)

run: deps venv
	@$(MAKE) --no-print-directory -j$$(nproc) all
	@mkdir -p $(OUT)
	$(MPIEXEC) -np $(NP) $(BUILD)/drape -options_file runs/hang.opts -output_file $(OUT)/hang.h5
	$(VENV)/bin/python scripts/render.py $(OUT)/hang.h5 -o $(OUT)/hang.png
	@echo "drape: wrote $(OUT)/hang.h5, $(OUT)/hang.xmf (ParaView) and $(OUT)/hang.png"

# The test files run on TEST_JOBS pytest-xdist workers (scripts/requirements.txt), a
# file's tests one after the other in one worker (their module fixtures once): one
# more than the cores, since a test's runs wait a third of their time (Open MPI's
# start, its singleton's daemon, files, Python) and a core would idle meanwhile;
# TEST_JOBS=1, or a Python without pytest-xdist (make check), runs them one at a time.
TEST_JOBS ?= $(shell echo $$(( $$(nproc 2>/dev/null || echo 1) + 1 )))
xdist = $(if $(filter-out 0 1,$(TEST_JOBS)),$(shell $(1) -c 'import xdist' 2>/dev/null && printf '%s' '-n $(TEST_JOBS) --dist loadfile'))

test: deps venv
	@$(MAKE) --no-print-directory -j$$(nproc) all
	DRAPE_BUILD=$(BUILD) $(VENV)/bin/python -m pytest -q $(call xdist,$(VENV)/bin/python) $(TESTS)

# build and test with what is installed: no apt-get, no pip
check: check-python
	@$(MAKE) --no-print-directory -j$$(nproc) all
	DRAPE_BUILD=$(BUILD) $(PYTHON) -m pytest -q $(call xdist,$(PYTHON)) $(TESTS)

# the benchmark table of README.md and BENCHMARKS.md, from the code as it is (several
# minutes; on a quiet machine): out/bench_core.csv, docs/bench_core.md (commit it) and
# the bench_core blocks of the two documents
bench: deps venv
	@$(MAKE) --no-print-directory -j$$(nproc) all
	DRAPE_BUILD=$(BUILD) $(VENV)/bin/python scripts/bench_core.py --out $(OUT)/bench_core.csv --doc docs/bench_core.md --update-docs

FORMAT_FILES ?= $(wildcard src/*.c src/*/*.c src/*/*.h src/*/*.cxx include/*.h tests/unit/*.c)
format:
	clang-format -i $(FORMAT_FILES)

# CI: fails, naming the lines, when make format would change a file
format-check:
	@command -v clang-format >/dev/null || { echo "drape: clang-format is missing; install it (Debian: apt-get install clang-format)"; exit 1; }
	@clang-format --dry-run --Werror $(FORMAT_FILES) || { echo "drape: these files are not formatted as .clang-format says: run make format"; exit 1; }

clean:
	rm -rf $(BUILD)

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
