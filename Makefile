# drape: build, run and test.
#   make run    set up what is missing, build, simulate runs/hang.opts, write HDF5 and a PNG
#   make test   set up what is missing, build, run every test
# The build reads PETSc's pkg-config data, compiles with mpicc (mpicxx for C++),
# and builds out of tree in $(BUILD) with generated dependencies.

BUILD   ?= build
VENV    ?= .venv
NP      ?= 2
OUT     ?= out
CFLAGS  ?= -O3 -g -fno-math-errno
CXXFLAGS ?= -O3 -g
# NATIVE=1 adds -march=native (faster on the build machine, may not run on others)
ifeq ($(NATIVE),1)
CFLAGS   += -march=native
CXXFLAGS += -march=native
endif

CC  := mpicc
CXX := mpicxx
PKGS := petsc hdf5-openmpi
DRAPE_CPPFLAGS := -Iinclude $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
DRAPE_CFLAGS   := -std=c11 -Wall -Wextra -Wno-unused-parameter -MMD -MP
DRAPE_CXXFLAGS := -std=c++17 -frounding-math -Wall -Wextra -Wno-unused-parameter -MMD -MP
LDLIBS := $(shell pkg-config --libs $(PKGS) 2>/dev/null) -lmetis -lgmp -lmpfr -lm

LIB_C   := $(filter-out src/main.c,$(wildcard src/*.c src/*/*.c))
LIB_CXX := $(wildcard src/*/*.cxx)
OBJ     := $(LIB_C:%.c=$(BUILD)/%.o) $(LIB_CXX:%.cxx=$(BUILD)/%.o)
LINK    := $(if $(LIB_CXX),$(CXX),$(CC))
UNIT    := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(wildcard tests/unit/*.c))

MPIEXEC ?= mpiexec $(if $(filter 0,$(shell id -u)),--allow-run-as-root) --oversubscribe

.PHONY: all deps venv run test bench format clean check-petsc
all: check-petsc $(BUILD)/drape $(UNIT)

check-petsc:
	@pkg-config --exists $(PKGS) || { echo "drape: PETSc/HDF5 development files not found by pkg-config; run 'make deps' (Debian: apt-get install petsc-dev libmetis-dev libhdf5-openmpi-dev libcgal-dev)"; exit 1; }

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(DRAPE_CPPFLAGS) $(DRAPE_CFLAGS) $(CFLAGS) -c $< -o $@

$(BUILD)/%.o: %.cxx
	@mkdir -p $(dir $@)
	$(CXX) $(DRAPE_CPPFLAGS) $(DRAPE_CXXFLAGS) $(CXXFLAGS) -c $< -o $@

$(BUILD)/libdrape.a: $(OBJ)
	ar rcs $@ $^

$(BUILD)/drape: $(BUILD)/src/main.o $(BUILD)/libdrape.a
	$(LINK) $(CFLAGS) -o $@ $^ $(LDLIBS)

$(BUILD)/tests/%: $(BUILD)/tests/unit/%.o $(BUILD)/libdrape.a
	@mkdir -p $(dir $@)
	$(LINK) $(CFLAGS) -o $@ $^ $(LDLIBS)

deps:
	@bash scripts/install-deps.sh

$(VENV)/.installed: scripts/requirements.txt
	@bash scripts/install-deps.sh --python $(VENV)
	@touch $@

venv: $(VENV)/.installed

run: deps venv
	@$(MAKE) --no-print-directory -j$$(nproc) all
	@mkdir -p $(OUT)
	$(MPIEXEC) -np $(NP) $(BUILD)/drape -options_file runs/hang.opts -output_file $(OUT)/hang.h5
	$(VENV)/bin/python scripts/render.py $(OUT)/hang.h5 -o $(OUT)/hang.png
	@echo "drape: wrote $(OUT)/hang.h5, $(OUT)/hang.xmf (ParaView) and $(OUT)/hang.png"

test: deps venv
	@$(MAKE) --no-print-directory -j$$(nproc) all
	DRAPE_BUILD=$(BUILD) $(VENV)/bin/python -m pytest -q tests

bench: deps venv
	@$(MAKE) --no-print-directory -j$$(nproc) all
	$(VENV)/bin/python scripts/bench_core.py --out $(OUT)/bench_core.csv

format:
	clang-format -i $(wildcard src/*.c src/*/*.c src/*/*.h src/*/*.cxx include/*.h tests/unit/*.c)

clean:
	rm -rf $(BUILD)

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
