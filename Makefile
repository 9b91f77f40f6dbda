# i2m: one non-recursive GNU Makefile (GNU make >= 3.82).
#
#   make                 bin/i2m, bin/i2m-info, bin/i2m-check, lib/libi2m.a, lib/libi2m.so (release);
#                        checks what building needs, installs nothing
#   make install         PREFIX (/usr/local), DESTDIR: programs, libraries, i2m.h, i2m.pc, man
#                        pages, the Python module; make uninstall
#   make check           every test: unit tests (release, then ASan+UBSan), tool and script
#                        tests, threaded tests under ThreadSanitizer, check-builds; installs
#                        missing Debian packages first when run as root
#   make check-builds    builds with MPICH, clang, cc without MPI (those installed); meshes with each
#   make bench           benchmarks; figures printed and written to bench/results/*.json
#   make bench-large     250 M voxels at default options, and about 150 M tets (minutes)
#   make bench-mpi       ranks x threads sweep on the knee atlas (bench/bench_mpi.sh; Table 2, Fig. 7)
#   make demo            meshes the knee atlas shipped in run/data end to end
#   make fuzz            libFuzzer harnesses of the readers, FUZZ_SECONDS (60) each (clang)
#   make DEBUG=1 | SANITIZE=address,undefined | SANITIZE=thread    other configurations
#   make V=1             show the commands
#   make MPI=mpich | CC=clang | CC=cc HAVE_MPI=0    other toolchains (see below)
#
# Objects go to build/<config>/.  Release binaries and the library go to bin/ and lib/;
# other configurations and toolchains keep theirs under build/<config>[-<tag>]/.

.DEFAULT_GOAL := all
SHELL := /bin/sh

# ---- dependencies -------------------------------------------------------------------------
# Checked once, before the toolchain is detected below (a fresh machine must not pick `cc`
# without MPI and only then install MPI).  Building (make, make install) only checks what
# building needs and never installs anything (tools/ensure-deps.sh build: one line naming what
# is missing); the goals that run things (check, demo, deps, bench, fuzz) check what they need
# too and, as root on Debian, install it (tools/ensure-deps.sh all).  The stamps record that a
# check passed.
RUN_GOALS := check check-% demo deps bench bench-% fuzz
ifneq ($(filter $(RUN_GOALS),$(MAKECMDGOALS)),)
  DEPS_MODE := all
else
  DEPS_MODE := build
endif
DEPS_STAMP := build/.deps-$(DEPS_MODE)-ok
ifeq ($(wildcard $(DEPS_STAMP)),)
  ifneq ($(filter-out clean uninstall print-%,$(or $(MAKECMDGOALS),all)),)
    ifneq ($(shell sh tools/ensure-deps.sh $(DEPS_MODE) >&2 && mkdir -p build && touch $(DEPS_STAMP) && echo ok),ok)
      $(error missing dependencies (see the line above))
    endif
  endif
endif

# ---- toolchain ----------------------------------------------------------------------------
# CC defaults to the MPI compiler wrapper MPICC: mpicc, or with MPI=mpich Debian's
# mpicc.mpich (MPI=openmpi: mpicc.openmpi; MPI=none or HAVE_MPI=0: no MPI, CC=cc).  With
# another compiler (make CC=clang) MPI's -I/-L/-l flags come from `$(MPICC) -show`, which
# Open MPI's and MPICH's wrappers both answer.  A toolchain other than the default one builds
# in build/<config>-<tag>/ with its bin/ and lib/ there (e.g. build/release-mpich/bin/i2m,
# build/release-clang/bin/i2m, build/release-cc-nompi/bin/i2m), so that none clobbers bin/.
mpi_flavour = $(if $(1),$(if $(findstring Open MPI,$(shell $(1) --showme:version 2>&1)),openmpi,$(if \
  $(findstring MPICH,$(shell $(1) -v </dev/null 2>/dev/null | head -n 1)),mpich,mpi)),nompi)
DEFAULT_MPICC := $(if $(shell command -v mpicc 2>/dev/null),mpicc)
ifeq ($(MPI),mpich)
  MPICC ?= mpicc.mpich
else ifeq ($(MPI),openmpi)
  MPICC ?= mpicc.openmpi
else ifeq ($(MPI),none)
  HAVE_MPI := 0
endif
# (make CC=mpicc.mpich: CC is the wrapper)
ifneq ($(origin CC),default)
  ifneq ($(filter mpi%,$(notdir $(firstword $(CC)))),)
    MPICC := $(CC)
  endif
endif
MPICC    ?= $(DEFAULT_MPICC)
HAVE_MPI ?= $(if $(MPICC),1,0)
ifeq ($(origin CC),default)
  CC := $(if $(filter 1,$(HAVE_MPI)),$(MPICC),cc)
endif
ifeq ($(HAVE_MPI),1)
  ifeq ($(shell command -v $(firstword $(MPICC) none) 2>/dev/null),)
    $(error HAVE_MPI=1 but no MPI compiler wrapper '$(MPICC)': install one (libopenmpi-dev, libmpich-dev), set MPICC=, or build with HAVE_MPI=0)
  endif
  # a plain compiler: MPI's flags from the wrapper
  ifneq ($(CC),$(MPICC))
    MPI_SHOW := $(shell $(MPICC) -show 2>/dev/null)
    CPPFLAGS += $(filter -I% -D%,$(MPI_SHOW))
    LDFLAGS  += $(filter -L% -Wl% -pthread,$(MPI_SHOW))
    LDLIBS   += $(filter -l%,$(MPI_SHOW))
  endif
endif
# the build tag: what differs from the default toolchain (compiler, MPI flavour)
CC_ID      := $(if $(filter $(MPICC),$(CC)),wrapper,$(notdir $(firstword $(CC))))
MPI_ID     := $(call mpi_flavour,$(if $(filter 1,$(HAVE_MPI)),$(MPICC)))
DEF_CC_ID  := $(if $(DEFAULT_MPICC),wrapper,cc)
DEF_MPI_ID := $(call mpi_flavour,$(DEFAULT_MPICC))
empty :=
space := $(empty) $(empty)
TAG := $(subst $(space),-,$(strip $(if $(filter-out $(DEF_CC_ID),$(CC_ID)),$(CC_ID)) \
  $(if $(filter-out $(DEF_MPI_ID),$(MPI_ID)),$(MPI_ID))))
OMPFLAGS ?= -fopenmp
FPFLAGS  ?= -ffp-contract=off
PYTHON   ?= /usr/bin/python3
OBJCOPY  ?= objcopy
LD_R     ?= ld -r

# ---- configuration ------------------------------------------------------------------------
ifdef SANITIZE
  ifeq ($(SANITIZE),thread)
    CONFIG := tsan
  else
    CONFIG := asan
  endif
  OPTFLAGS ?= -O1 -g -fno-omit-frame-pointer -fsanitize=$(SANITIZE) -fno-sanitize-recover=all -DI2M_DEBUG
  SANFLAGS := -fsanitize=$(SANITIZE)
else ifdef DEBUG
  CONFIG := debug
  OPTFLAGS ?= -O0 -g -DI2M_DEBUG
else
  CONFIG := release
  OPTFLAGS ?= -O3 -g
endif

BUILD := build/$(CONFIG)$(if $(TAG),-$(TAG))
ifeq ($(CONFIG)$(TAG),release)
  BINDIR := bin
  LIBDIR := lib
else
  BINDIR := $(BUILD)/bin
  LIBDIR := $(BUILD)/lib
endif

# position-independent objects: the same objects make libi2m.a and libi2m.so (without semantic
# interposition where the compiler knows the flag, so that -fPIC costs the kernel nothing)
PICFLAGS  ?= -fPIC $(if $(shell $(CC) -fno-semantic-interposition -x c -c /dev/null -o /dev/null 2>/dev/null && echo y),-fno-semantic-interposition)
WARNFLAGS := -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes $(if $(WERROR),-Werror)
CPPFLAGS  += -Iinclude -D_POSIX_C_SOURCE=200809L -DI2M_HAVE_MPI=$(HAVE_MPI)
ALL_CFLAGS = -std=c11 $(WARNFLAGS) $(OPTFLAGS) $(FPFLAGS) $(OMPFLAGS) $(PICFLAGS) -MMD -MP $(CFLAGS)
LDLIBS    += -lz -lhwloc -lm
TEST_LDLIBS := -lcunit

ifeq ($(V),1)
  Q :=
else
  Q := @
endif

# ---- sources ------------------------------------------------------------------------------
LAYERS     := base geom image delaunay refine threads dist io api
LIB_SRC    := $(foreach l,$(LAYERS),$(wildcard src/$(l)/*.c))
LIB_OBJ    := $(LIB_SRC:%.c=$(BUILD)/%.o)
# lib/libi2m.a and lib/libi2m.so export only the i2m_ names (the .a holds one object whose other
# globals are made local; the .so has a version script); the unit tests and fuzzers, which call
# internals, link every object from $(BUILD)/libi2m-internal.a
LIB        := $(LIBDIR)/libi2m.a
SO_VERSION := 0
VERSION    := 0.1
SO_NAME    := libi2m.so.$(SO_VERSION)
SHLIB      := $(LIBDIR)/libi2m.so
INTERNAL_LIB := $(BUILD)/libi2m-internal.a

CLI_SRC    := $(wildcard src/cli/*.c)
INFO_SRC   := tools/i2m_info.c
CHECK_SRC  := $(wildcard tools/check/*.c)
MKIMG_SRC  := $(wildcard tools/i2m_mkimage.c)
BENCH_SRC  := $(wildcard bench/*.c)
UNIT_SRC   := $(wildcard tests/unit/test_*.c)
UNIT_BIN   := $(UNIT_SRC:tests/unit/%.c=$(BUILD)/tests/%)

PROGRAMS := $(BINDIR)/i2m-info $(BINDIR)/i2m-check
ifneq ($(MKIMG_SRC),)
  PROGRAMS += $(BINDIR)/i2m-mkimage
endif
ifneq ($(CLI_SRC),)
  PROGRAMS += $(BINDIR)/i2m
endif

# ---- build rules --------------------------------------------------------------------------
.SECONDARY:
.PHONY: man install uninstall FORCE fuzz fuzz-bin bench-large all lib programs unit-tests mpi-tools check check-unit check-scripts check-layers check-tsan check-full check-builds bench bench-mpi demo deps clean

all: $(PROGRAMS) $(LIB) $(SHLIB)
lib: $(LIB) $(SHLIB)
programs: $(PROGRAMS)

$(DEPS_STAMP):
	$(Q)sh tools/ensure-deps.sh $(DEPS_MODE)
	$(Q)mkdir -p build && touch $@

# the compiler and the flags that change the objects: when they change (MPI installed since,
# another OPTFLAGS), every object of this build directory is rebuilt
BUILD_LINE := $(CC) $(CPPFLAGS) $(OPTFLAGS) $(FPFLAGS) $(OMPFLAGS) $(PICFLAGS) $(CFLAGS)
$(BUILD)/.build-line: FORCE | $(DEPS_STAMP)
	@mkdir -p $(@D)
	@if [ "$$(cat $@ 2>/dev/null)" != '$(BUILD_LINE)' ]; then echo '$(BUILD_LINE)' > $@; fi
FORCE:

$(BUILD)/%.o: %.c $(BUILD)/.build-line | $(DEPS_STAMP)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) $(CPPFLAGS) $(ALL_CFLAGS) -c $< -o $@

$(INTERNAL_LIB): $(LIB_OBJ)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  AR      $@")
	$(Q)rm -f $@ && ar rcs $@ $^

# one relocatable object of the whole library, every global but the i2m_ ones made local
$(BUILD)/libi2m.o: $(LIB_OBJ)
	@$(if $(Q),echo "  LD -r   $@")
	$(Q)$(LD_R) -o $@ $^
	$(Q)if command -v $(OBJCOPY) >/dev/null 2>&1; then $(OBJCOPY) --wildcard --keep-global-symbol='i2m_*' $@; \
	  else echo "  (no $(OBJCOPY): $(LIB) also exports the internal names)"; fi

$(LIB): $(BUILD)/libi2m.o
	@mkdir -p $(@D)
	@$(if $(Q),echo "  AR      $@")
	$(Q)rm -f $@ && ar rcs $@ $^

$(SHLIB): $(LIB_OBJ) tools/libi2m.map
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) -shared $(ALL_CFLAGS) $(SANFLAGS) -Wl,-soname,$(SO_NAME) -Wl,--version-script=tools/libi2m.map \
	  -o $(LIBDIR)/$(SO_NAME) $(LIB_OBJ) $(LDFLAGS) $(LDLIBS)
	$(Q)ln -sf $(SO_NAME) $@

$(BINDIR)/i2m: $(CLI_SRC:%.c=$(BUILD)/%.o) $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(ALL_CFLAGS) $(SANFLAGS) -o $@ $^ $(LDFLAGS) $(LDLIBS)

$(BINDIR)/i2m-info: $(INFO_SRC:%.c=$(BUILD)/%.o) $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(ALL_CFLAGS) $(SANFLAGS) -o $@ $^ $(LDFLAGS) $(LDLIBS)

$(BINDIR)/i2m-check: $(CHECK_SRC:%.c=$(BUILD)/%.o) $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(ALL_CFLAGS) $(SANFLAGS) -o $@ $^ $(LDFLAGS) $(LDLIBS)

$(BINDIR)/i2m-mkimage: $(MKIMG_SRC:%.c=$(BUILD)/%.o) $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(ALL_CFLAGS) $(SANFLAGS) -o $@ $^ $(LDFLAGS) $(LDLIBS)

$(BUILD)/tests/%: $(BUILD)/tests/unit/%.o $(INTERNAL_LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(ALL_CFLAGS) $(SANFLAGS) -o $@ $^ $(LDFLAGS) $(LDLIBS) $(TEST_LDLIBS)

$(BUILD)/bench/%: $(BUILD)/bench/%.o $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(ALL_CFLAGS) $(SANFLAGS) -o $@ $^ $(LDFLAGS) $(LDLIBS)

# MPI test tools (tests/mpi/, only with MPI): the PMPI wrapper that checks MPI_THREAD_FUNNELED,
# preloaded into bin/i2m by tests/scripts/test_mpi_funneled.sh, and a program that breaks
# FUNNELED on purpose.  Built without the sanitizers: a preloaded library must not need a
# runtime that the program loads after it.
MPI_TOOLS :=
ifeq ($(HAVE_MPI),1)
  MPI_TOOLS := $(BUILD)/tests/pmpi_funneled.so $(BUILD)/tests/funneled_bad
endif
MPI_TOOL_FLAGS = -std=c11 $(WARNFLAGS) -O2 -g -pthread $(CFLAGS)

$(BUILD)/tests/pmpi_funneled.so: tests/mpi/pmpi_funneled.c | $(DEPS_STAMP)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(CPPFLAGS) $(MPI_TOOL_FLAGS) -fPIC -shared -o $@ $<

$(BUILD)/tests/funneled_bad: tests/mpi/funneled_bad.c | $(DEPS_STAMP)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(CPPFLAGS) $(MPI_TOOL_FLAGS) -o $@ $<

mpi-tools: $(MPI_TOOLS)

unit-tests: $(UNIT_BIN) $(MPI_TOOLS)

# ---- tests --------------------------------------------------------------------------------
# check: release build and unit tests, the same unit tests under ASan+UBSan, the script
# tests (tools, writers with meshio, error paths, end-to-end), threaded tests under TSan.
# (the builds use every core even when make check itself was started without -j; the tests
# run one at a time)
CHECK_JOBS ?= $(if $(findstring j,$(firstword $(MAKEFLAGS))),,-j$(shell getconf _NPROCESSORS_ONLN 2>/dev/null || echo 2))
check: $(DEPS_STAMP)
	$(Q)$(MAKE) --no-print-directory $(CHECK_JOBS) WERROR=1 all unit-tests
	$(Q)$(MAKE) --no-print-directory WERROR=1 check-layers
	$(Q)$(MAKE) --no-print-directory WERROR=1 check-unit
	$(Q)$(MAKE) --no-print-directory $(CHECK_JOBS) WERROR=1 SANITIZE=address,undefined all unit-tests
	$(Q)$(MAKE) --no-print-directory WERROR=1 SANITIZE=address,undefined check-unit
	$(Q)$(MAKE) --no-print-directory WERROR=1 check-scripts
	$(Q)$(MAKE) --no-print-directory $(CHECK_JOBS) WERROR=1 SANITIZE=thread all $(BUILD_TSAN_TESTS)
	$(Q)sh tests/run_tsan.sh
	$(Q)sh tests/builds.sh
	@echo "make check: all tests passed"

# the threaded code under ThreadSanitizer (tests/run_tsan.sh runs these)
BUILD_TSAN_TESTS := build/tsan/tests/test_threads_refine

check-unit: $(UNIT_BIN)
	$(Q)sh tests/run_unit.sh $(BUILD)/tests $(CONFIG)

check-scripts: all $(MPI_TOOLS)
	$(Q)sh tests/run_scripts.sh

check-layers:
	$(Q)sh tools/check_layers.sh

# every image of ../shared/data at 1, 2 and 4 threads, in both modes, and at 1 and 2 threads with
# --sliver-angle 15 within 15..160 degrees (about thirty minutes on 2 cores)
ALL_IMAGES := liver.inr.gz spine_verse009.nii.gz brain_kmeans_noisy.nii.gz vertebrae_vbseg.mha \
  knee_atlas.nrrd abdominal_atlas.nrrd head_colin27.nii.gz
check-full: all
	$(Q)I2M_IMAGES="$(ALL_IMAGES)" I2M_DATA="$${I2M_DATA:-../shared/data}" I2M_BIN=bin PYTHON=$(PYTHON) \
	  I2M_TMP=$$(mktemp -d) sh tests/scripts/test_threads_real_images.sh
	$(Q)I2M_IMAGES="$(ALL_IMAGES)" I2M_DATA="$${I2M_DATA:-../shared/data}" I2M_BIN=bin PYTHON=$(PYTHON) \
	  I2M_TMP=$$(mktemp -d) sh tests/scripts/test_deterministic.sh
	$(Q)I2M_IMAGES="$(ALL_IMAGES)" I2M_DATA="$${I2M_DATA:-../shared/data}" I2M_BIN=bin PYTHON=$(PYTHON) \
	  I2M_TMP=$$(mktemp -d) sh tests/scripts/test_slivers_images.sh

# the other toolchains that are installed (MPICH, clang, cc without MPI), each in its own
# build directory, each meshing a small image (tests/builds.sh; about a minute from scratch)
check-builds: $(DEPS_STAMP)
	$(Q)sh tests/builds.sh

check-tsan:
	$(Q)$(MAKE) --no-print-directory WERROR=1 SANITIZE=thread all $(BUILD_TSAN_TESTS)
	$(Q)sh tests/run_tsan.sh

# ---- fuzzing ------------------------------------------------------------------------------
# make fuzz: libFuzzer harnesses (tests/fuzz/) for the image readers and i2m-check's mesh
# readers, built with clang, ASan and UBSan in build/asan-clang/, each run FUZZ_SECONDS.
FUZZ_SECONDS ?= 60
FUZZ_BIN := $(patsubst tests/fuzz/%.c,$(BUILD)/fuzz/%,$(wildcard tests/fuzz/fuzz_*.c))
CHECK_LIB_OBJ := $(filter-out %/check_main.o,$(CHECK_SRC:%.c=$(BUILD)/%.o))
$(BUILD)/fuzz/%: tests/fuzz/%.c tests/fuzz/fuzz_common.h $(CHECK_LIB_OBJ) $(INTERNAL_LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) $(CPPFLAGS) -Itools/check $(ALL_CFLAGS) -fsanitize=fuzzer,address,undefined -o $@ $< $(CHECK_LIB_OBJ) $(INTERNAL_LIB) \
	  $(LDFLAGS) $(LDLIBS)
fuzz-bin: $(FUZZ_BIN)

fuzz: $(DEPS_STAMP) all
	$(Q)command -v clang >/dev/null || { echo "make fuzz needs clang (apt-get install clang)" >&2; exit 1; }
	$(Q)$(MAKE) --no-print-directory CC=clang SANITIZE=fuzzer-no-link,address,undefined fuzz-bin
	$(Q)sh tests/fuzz/run.sh build/asan-clang/fuzz $(FUZZ_SECONDS)

# ---- benchmarks and demo --------------------------------------------------------------------
bench: all $(BENCH_SRC:bench/%.c=$(BUILD)/bench/%)
	$(Q)sh bench/run.sh $(BUILD)/bench

# i2m at scale: 250 M voxels at default options, then about 150 M tets (bench/large.sh; minutes)
bench-large: all
	$(Q)I2M_DATA="$${I2M_DATA:-../shared/data}" PYTHON=$(PYTHON) sh bench/large.sh

# the MPI sweep (I2M_BENCH_REPEATS, I2M_BENCH_CONFIGS, I2M_BENCH_IMAGE, I2M_BENCH_OPTS: see the script)
# (the launcher that goes with the wrapper: mpicc.mpich -> mpirun.mpich)
MPIRUN ?= $(patsubst mpicc%,mpirun%,$(notdir $(firstword $(MPICC))))
bench-mpi: all
	$(Q)I2M="$(CURDIR)/$(BINDIR)/i2m" MPIRUN="$(MPIRUN)" sh bench/bench_mpi.sh

demo: all
	$(Q)sh run/demo.sh

# ---- install ------------------------------------------------------------------------------
# make install PREFIX=/opt/i2m DESTDIR=/tmp/stage: the programs, libi2m.a and libi2m.so, the
# public header i2m.h, the pkg-config file i2m.pc (pkg-config --cflags --libs i2m) and the man
# pages; make uninstall removes them.
PREFIX     ?= /usr/local
I_BIN      := $(DESTDIR)$(PREFIX)/bin
I_LIB      := $(DESTDIR)$(PREFIX)/lib
I_INC      := $(DESTDIR)$(PREFIX)/include
I_MAN      := $(DESTDIR)$(PREFIX)/share/man/man1
I_PC       := $(I_LIB)/pkgconfig
I_PY       := $(DESTDIR)$(PREFIX)/share/i2m/python
INSTALLED_PROGRAMS := i2m i2m-check i2m-info
# the man pages come from the programs' own --help (tools/man.sh)
MAN_PAGES  := $(addprefix $(BUILD)/man/,$(addsuffix .1,$(INSTALLED_PROGRAMS)))
MAN_SUMMARY_i2m       := labelled tetrahedral meshes from segmented 3D images
MAN_SUMMARY_i2m-check := independent checks of a labelled tetrahedral mesh (validity, quality, fidelity)
MAN_SUMMARY_i2m-info  := what a 3D label image holds (geometry, labels, voxel counts)
# the libraries the shared library needs at run time are its own; a static link needs these
PC_PRIVATE := $(OMPFLAGS) $(filter -L% -l%,$(LDFLAGS) $(LDLIBS)) $(if $(filter 1,$(HAVE_MPI)),$(filter -L% -l% -Wl%,$(shell $(MPICC) -show 2>/dev/null)))

$(BUILD)/i2m.pc: FORCE
	@mkdir -p $(@D)
	@printf '%s\n' 'prefix=$(PREFIX)' 'libdir=$${prefix}/lib' 'includedir=$${prefix}/include' '' \
	  'Name: i2m' 'Description: parallel Delaunay image-to-mesh conversion of labelled 3D images' \
	  'Version: $(VERSION)' 'Cflags: -I$${includedir}' 'Libs: -L$${libdir} -Wl,-rpath,$${libdir} -li2m' \
	  'Libs.private: $(strip $(PC_PRIVATE))' > $@

$(BUILD)/man/%.1: $(BINDIR)/% tools/man.sh
	@mkdir -p $(@D)
	$(Q)sh tools/man.sh $< $* "$(MAN_SUMMARY_$*)" > $@

man: $(MAN_PAGES)

install: all $(BUILD)/i2m.pc $(MAN_PAGES)
	install -d $(I_BIN) $(I_LIB) $(I_INC) $(I_MAN) $(I_PC) $(I_PY)
	install -m 755 $(addprefix $(BINDIR)/,$(INSTALLED_PROGRAMS)) $(I_BIN)
	install -m 644 $(LIB) $(I_LIB)
	install -m 755 $(LIBDIR)/$(SO_NAME) $(I_LIB)
	ln -sf $(SO_NAME) $(I_LIB)/libi2m.so
	install -m 644 include/i2m.h $(I_INC)
	install -m 644 $(BUILD)/i2m.pc $(I_PC)
	install -m 644 $(MAN_PAGES) $(I_MAN)
	install -m 644 python/i2m.py $(I_PY)

uninstall:
	rm -f $(addprefix $(I_BIN)/,$(INSTALLED_PROGRAMS)) $(I_LIB)/libi2m.a $(I_LIB)/$(SO_NAME) $(I_LIB)/libi2m.so \
	  $(I_INC)/i2m.h $(I_PC)/i2m.pc $(addprefix $(I_MAN)/,$(notdir $(MAN_PAGES))) $(I_PY)/i2m.py
	-rmdir $(I_PY) $(DESTDIR)$(PREFIX)/share/i2m 2>/dev/null

deps:
	$(Q)sh tools/ensure-deps.sh

clean:
	rm -rf build bin lib

# make print-BINDIR, print-CC ...: a variable's value (for scripts)
print-%:
	@echo '$($*)'

-include $(wildcard $(BUILD)/src/*/*.d $(BUILD)/tools/*.d $(BUILD)/tools/check/*.d $(BUILD)/tests/unit/*.d $(BUILD)/bench/*.d)
