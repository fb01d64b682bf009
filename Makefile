# pmtk: SIMD packet photon mapping as small programs that exchange files.
#
#   make            build every program into bin/
#   make check      the developer's loop, under 60 s, as any user: unit tests, golden files, the
#                   CLI contract, one small render (CHECK_SCRIPTS)
#   make test       CI's whole suite, about 9 minutes twice: install missing Debian packages (needs
#                   root for apt-get), build with -Werror, run every test, pipelines/slurm on a
#                   one-node Slurm cluster started here (needs root for munged, slurmctld, slurmd),
#                   then the same tests under AddressSanitizer + UBSan
#   make install    PREFIX=/usr/local DESTDIR=: the pmtk command, the programs in libexec/pmtk,
#                   libpmtk.so.1, pmtk.h, pmtk.pc, man pages (help2man)
#   make test-extreme  only the stiff and extreme cases (tests/stage/extreme.sh; also part of test)
#   make asan       sanitizer build into build/asan/bin
#   make demo       render the Cornell box with what exists (see README)
#   make bench      benchmarks into docs/benchmarks.md (BENCH=PATTERN: only those sections)
#   make bench-quick the same on smaller inputs, in under two minutes
#   make fuzz       libFuzzer targets for every reader, past the checksum too (clang; docs/fuzzing.md), not part of test
#   make deps       install the Debian packages (apt-get, when root)
#   make format     lay out every C file as .clang-format says (format-check: only check; part of test)
#   make clean
#
# Out-of-tree objects in $(BUILD); dependencies from -MMD -MP; a change of flags
# rebuilds everything; quiet unless V=1.

BUILD ?= build
BIN ?= bin
# gcc unless CC is given on the command line or in the environment (make's own default is cc).
ifeq ($(origin CC),default)
CC := gcc
endif
SAN ?=
# Warnings are errors everywhere, so that `make` and `make test` share one build; WERROR=
# (empty) turns that off for experiments.
WERROR ?= 1

# Debian packages this project builds, tests and runs with (README says why each).
DEBS := gcc make pkg-config libembree-dev libopenexr-dev libassimp-dev libjansson-dev \
        libpng-dev libjpeg62-turbo-dev libxxhash-dev libcmocka-dev openexr jq gnuplot-nox clang-format \
        assimp-testmodels help2man
# The Python package python/pmtk (docs/python.md, tests/stage/python.sh): numpy and xxhash read
# the files; matplotlib draws docs/python.md's error-against-time plot.
DEBS += python3 python3-numpy python3-xxhash python3-matplotlib

ifeq ($(V),1)
Q :=
else
Q := @
endif

PKGS := OpenEXR assimp jansson libpng libxxhash
# Debian's libembree-dev ships no .pc file; use pkg-config when there is one.
EMBREE_CFLAGS := $(shell pkg-config --cflags embree3 2>/dev/null)
EMBREE_LIBS := $(shell pkg-config --libs embree3 2>/dev/null || echo -lembree3)
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
# Only OpenEXR's C API (OpenEXRCore) is used; the C++ libraries are not linked.
PKG_LIBS := -lOpenEXRCore-3_1 $(shell pkg-config --libs assimp jansson libpng libxxhash 2>/dev/null)
CMOCKA_LIBS := $(shell pkg-config --libs cmocka 2>/dev/null || echo -lcmocka)

# snprintf truncation is how this code bounds names and messages, so it is not warned about.
WARN := -Wall -Wextra -Wshadow -Wstrict-prototypes -Wmissing-prototypes -Wpointer-arith -Wformat=2 \
        -Wundef -Wvla -Wno-unused-parameter -Wno-format-truncation
CFLAGS ?= -O2 -g
# Includes name their layer ("base/error.h", "formats/formats.h"), never a ../ path.
INCLUDES := -I. -Icommon
ALL_CFLAGS := -std=c17 -D_GNU_SOURCE $(INCLUDES) $(WARN) $(if $(WERROR),-Werror,) -fopenmp -fno-math-errno \
              $(SAN) $(PKG_CFLAGS) $(EMBREE_CFLAGS) $(CFLAGS)
ALL_LDFLAGS := -fopenmp $(SAN) $(LDFLAGS)
# libjpeg-turbo (texture JPEGs) ships libjpeg.pc only in newer Debian releases.
LIBS := $(EMBREE_LIBS) $(PKG_LIBS) -ljpeg -lm

# ---- libpmtk (issue 31): the public API (include/pmtk.h, common/api), the shared library ----
# Every object is position-independent and hides its symbols, so the programs (linked with the
# static archive) and libpmtk.so (exporting only pmtk_*, common/api/libpmtk.map) are the same
# objects. SO_MAJOR is PMTK_API_VERSION.
ALL_CFLAGS += -Iinclude -fPIC -fvisibility=hidden -DPMTK_BUILDING
SO_MAJOR := 1
SO_VERSION := $(SO_MAJOR).0.0
SHLIB := $(BUILD)/libpmtk.so.$(SO_VERSION)
SHLIB_MAP := common/api/libpmtk.map
# ---- end libpmtk ----

# The library's layers (docs/architecture.md): base, math, formats, physics, then render,
# photonmap and image, then engine (the render driver's library) over them all.
LAYERS := common/base common/math formats common/physics common/render common/photonmap common/image common/engine \
          common/api
LIB_SRC := $(foreach d,$(LAYERS),$(wildcard $(d)/*.c))
LIB_OBJ := $(LIB_SRC:%.c=$(BUILD)/%.o)
LIB := $(BUILD)/libpmtk.a

STAGES := $(notdir $(wildcard stages/*))
PROGS := $(STAGES:%=$(BIN)/%)

UNIT_SRC := $(wildcard tests/unit/*.c)
UNIT_OBJ := $(UNIT_SRC:%.c=$(BUILD)/%.o)
UNIT := $(BUILD)/tests/unit-tests
TESTGEN := $(BUILD)/tests/pm-testgen
EXRDUMP := $(BUILD)/tests/pm-exrdump
ATRIUM_GEN := $(BUILD)/scenes/make-atrium
ATRIUM_OBJ := scenes/atrium/atrium.obj
ATRIUM_SKY := scenes/atrium/atrium-sky.obj scenes/atrium/atrium-sky.mtl scenes/atrium/stone.png scenes/atrium/floor.png
CAUSTIC_GEN := $(BUILD)/scenes/make-caustic
CAUSTIC_OBJ := scenes/caustic/caustic.obj

# The C sources clang-format keeps (.clang-format); the generated and fuzz-regression files are not C.
FORMAT_SRC = $(shell git ls-files '*.c' '*.h' 2>/dev/null)

.PHONY: format format-check all test test-run test-extreme test-slurm asan test-asan demo bench bench-quick fuzz deps clean check-deps
# Keep the stages' objects: they are intermediate to the pattern rule, and make would
# otherwise delete them and rebuild them next time. Only they are named: a bare .SECONDARY:
# makes every target an intermediate, and make then never builds a new tests/unit/*.c's
# object while the unit-test binary is newer than its sources.
.SECONDARY: $(STAGES:%=$(BUILD)/stages/%/main.o)
all: $(PROGS) $(ATRIUM_OBJ) $(ATRIUM_SKY) $(CAUSTIC_OBJ) $(SHLIB)

# Rebuild everything when the flags change.
FLAGS_FILE := $(BUILD)/.flags
FLAGS_NOW := $(CC) $(ALL_CFLAGS) $(ALL_LDFLAGS) $(LIBS)
# FORCE is phony: were it an intermediate file (as under a bare .SECONDARY:), a missing FORCE
# would never make .flags out of date, and a change of flags would rebuild nothing.
.PHONY: FORCE
$(FLAGS_FILE): FORCE
	@mkdir -p $(@D)
	@echo '$(FLAGS_NOW)' | cmp -s - $@ || echo '$(FLAGS_NOW)' > $@
FORCE:

$(BUILD)/%.o: %.c $(FLAGS_FILE)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<",true)
	$(Q)$(CC) $(ALL_CFLAGS) -MMD -MP -c $< -o $@

# The scene cache holds this build's structs (common/render/scene_cache.c): its BUILD key is a
# hash of the library's sources and the flags, kept in a stamp rewritten only when it changes,
# and compiled into scene_cache.o alone.
SCENE_CACHE_BUILD := $(BUILD)/.scene-cache-build
$(SCENE_CACHE_BUILD): $(LIB_SRC) $(foreach d,$(LAYERS),$(wildcard $(d)/*.h)) $(FLAGS_FILE)
	@mkdir -p $(@D)
	@h=$$(cat $^ | sha256sum | cut -c1-16); echo "$$h" | cmp -s - $@ || echo "$$h" > $@
$(BUILD)/common/render/scene_cache.o: common/render/scene_cache.c $(FLAGS_FILE) $(SCENE_CACHE_BUILD)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<",true)
	$(Q)$(CC) $(ALL_CFLAGS) -DPM_SCENE_CACHE_BUILD="\"$$(cat $(SCENE_CACHE_BUILD))\"" -MMD -MP -c $< -o $@
$(LIB): $(LIB_OBJ)
	@$(if $(Q),echo "  AR      $@",true)
	$(Q)rm -f $@ && ar rcs $@ $^

# ---- libpmtk: the shared library, its pkg-config file, man pages, make install ----
# libpmtk.so.1 (soname) -> libpmtk.so.1.0.0; only the pmtk_* names are exported.
$(SHLIB): $(LIB_OBJ) $(SHLIB_MAP)
	@$(if $(Q),echo "  SHLIB   $@",true)
	$(Q)$(CC) -shared $(ALL_LDFLAGS) -Wl,-soname,libpmtk.so.$(SO_MAJOR) -Wl,--version-script=$(SHLIB_MAP) \
	    -Wl,--no-undefined $(LIB_OBJ) $(LIBS) -o $@
	$(Q)ln -sf $(notdir $@) $(BUILD)/libpmtk.so.$(SO_MAJOR) && ln -sf $(notdir $@) $(BUILD)/libpmtk.so

# make install PREFIX=/usr/local DESTDIR=: the pmtk command in bin/, the programs in
# libexec/pmtk/ (so that a bare `composite` on the PATH stays ImageMagick's; `pmtk composite`
# runs ours), the library, its header and pkg-config file, and man pages made from --help.
PREFIX ?= /usr/local
DESTDIR ?=
LIBDIR ?= $(PREFIX)/lib
MAN_DIR := $(BUILD)/man
.PHONY: install man
man: $(PROGS)
	@mkdir -p $(MAN_DIR)
	$(Q)for p in $(STAGES); do \
	    page=pmtk-$$p; [ $$p = pmtk ] && page=pmtk; \
	    desc=$$($(BIN)/$$p --help | sed -n 2p | sed -E 's/[.:;]? *\(.*//; s/\.$$//' | cut -c1-80); \
	    help2man --no-info --no-discard-stderr --section=1 --source=pmtk --name="$$desc" \
	        --output=$(MAN_DIR)/$$page.1 $(BIN)/$$p || exit 1; \
	done

install: all man
	@command -v help2man >/dev/null || { echo "install: needs help2man (make deps)" >&2; exit 1; }
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/libexec/pmtk $(DESTDIR)$(LIBDIR)/pkgconfig \
	    $(DESTDIR)$(PREFIX)/include $(DESTDIR)$(PREFIX)/share/man/man1
	install -m 755 $(BIN)/pmtk $(DESTDIR)$(PREFIX)/bin/pmtk
	install -m 755 $(filter-out $(BIN)/pmtk,$(PROGS)) $(DESTDIR)$(PREFIX)/libexec/pmtk/
	install -m 755 $(SHLIB) $(DESTDIR)$(LIBDIR)/
	ln -sf $(notdir $(SHLIB)) $(DESTDIR)$(LIBDIR)/libpmtk.so.$(SO_MAJOR)
	ln -sf $(notdir $(SHLIB)) $(DESTDIR)$(LIBDIR)/libpmtk.so
	install -m 644 include/pmtk.h $(DESTDIR)$(PREFIX)/include/pmtk.h
	install -m 644 $(MAN_DIR)/*.1 $(DESTDIR)$(PREFIX)/share/man/man1/
	sed -e 's|@PREFIX@|$(PREFIX)|; s|@LIBDIR@|$(LIBDIR)|; s|@VERSION@|$(shell sed -n "s/.*PM_VERSION_STRING \"\(.*\)\"/\1/p" common/base/version.h)|' \
	    common/api/pmtk.pc.in >$(DESTDIR)$(LIBDIR)/pkgconfig/pmtk.pc
# ---- end libpmtk ----

$(BIN)/%: $(BUILD)/stages/%/main.o $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LINK    $@",true)
	$(Q)$(CC) $(ALL_LDFLAGS) $< $(LIB) $(LIBS) -o $@

$(UNIT): $(UNIT_OBJ) $(LIB)
	@mkdir -p $(@D)
	@$(if $(Q),echo "  LINK    $@",true)
	$(Q)$(CC) $(ALL_LDFLAGS) $(UNIT_OBJ) $(LIB) $(LIBS) $(CMOCKA_LIBS) -o $@

$(TESTGEN): $(BUILD)/tests/pm-testgen.o $(LIB)
	@mkdir -p $(@D)
	$(Q)$(CC) $(ALL_LDFLAGS) $< $(LIB) $(LIBS) -o $@

$(EXRDUMP): $(BUILD)/tests/pm-exrdump.o $(LIB)
	@mkdir -p $(@D)
	$(Q)$(CC) $(ALL_LDFLAGS) $< $(LIB) $(LIBS) -o $@

# The generator builds with fixed flags: its output must not change with CFLAGS or SAN.
$(ATRIUM_GEN): scenes/atrium/make-atrium.c
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<",true)
	$(Q)$(CC) -std=c17 -O2 $(WARN) $(if $(WERROR),-Werror,) $< -lpng -lm -o $@

$(ATRIUM_OBJ) scenes/atrium/atrium.mtl $(ATRIUM_SKY) &: $(ATRIUM_GEN)
	@$(if $(Q),echo "  GEN     $@",true)
	$(Q)$(ATRIUM_GEN) -o scenes/atrium

$(CAUSTIC_GEN): scenes/caustic/make-caustic.c
	@mkdir -p $(@D)
	@$(if $(Q),echo "  CC      $<",true)
	$(Q)$(CC) -std=c17 -O2 $(WARN) $(if $(WERROR),-Werror,) $< -lm -o $@

$(CAUSTIC_OBJ) scenes/caustic/caustic.mtl &: $(CAUSTIC_GEN)
	@$(if $(Q),echo "  GEN     $@",true)
	$(Q)$(CAUSTIC_GEN) -o scenes/caustic

# ---- tests ----
check-deps:
	@sh tests/install-deps.sh $(DEBS)

# Every C file as clang-format lays it out (.clang-format); a difference names the file and
# the first lines, and `make format` rewrites them.
format-check:
	@command -v clang-format >/dev/null || { echo "format-check: needs clang-format (make deps)" >&2; exit 1; }
	@bad=0; for f in $(FORMAT_SRC); do \
	    if ! clang-format --dry-run --Werror "$$f" 2>/dev/null; then \
	        echo "format-check: '$$f' is not as clang-format lays it out (make format):" >&2; \
	        clang-format "$$f" | diff -u "$$f" - | sed -n '3,12p' >&2; bad=1; \
	    fi; \
	done; [ $$bad = 0 ] && echo "format-check: $(words $(FORMAT_SRC)) files as .clang-format lays them out"

format:
	$(Q)clang-format -i $(FORMAT_SRC)

# Targets that install packages first re-run make, so that the pkg-config look-ups above
# happen after the packages are there (they are evaluated when the Makefile is read).
test: check-deps
	$(Q)$(MAKE) --no-print-directory format-check
	$(Q)$(MAKE) --no-print-directory test-run
	$(Q)$(MAKE) --no-print-directory test-slurm
	$(Q)$(MAKE) --no-print-directory test-asan

# ---- make check: the developer's loop (issue 31) ----
# The unit tests, the golden files (formats, simd-gather), the CLI contract (cli, exitcodes,
# pmtk), the include layers, the tiers themselves (testrun) and one small render (pm-render),
# as any user: no apt-get, no Slurm, no sanitizer pass. 38 s wall (27 CPU s, 588 checks) on the
# 2-core machine at load 5.5; the goal is under 60 s. `make test` is the whole suite for CI.
CHECK_SCRIPTS := cli exitcodes pmtk formats compare composite simd-gather layers testrun pm-render
.PHONY: check
check: all $(UNIT) $(TESTGEN) $(EXRDUMP)
	$(Q)STAGE_SCRIPTS="$(CHECK_SCRIPTS)" BIN=$(abspath $(BIN)) BUILD=$(abspath $(BUILD)) bash tests/run
# ---- end make check ----

test-run: all $(UNIT) $(TESTGEN) $(EXRDUMP)
	$(Q)BIN=$(abspath $(BIN)) BUILD=$(abspath $(BUILD)) bash tests/run

# pipelines/slurm on a one-node Slurm cluster started on this machine (tests/slurm/cluster:
# munged, slurmctld and slurmd as root, torn down after); it fails when they cannot start.
# The whole run has a limit (about 2 minutes here; each render in it has one of its own): past
# it, timeout signals the run, whose renders cancel their jobs and whose cluster is torn down.
SLURM_DEBS := slurm-wlm slurm-client munge iproute2
SLURM_TEST_TIMEOUT ?= 1200
test-slurm: all
	@sh tests/install-deps.sh $(SLURM_DEBS)
	$(Q)BIN=$(abspath $(BIN)) timeout -k 60 $(SLURM_TEST_TIMEOUT) bash tests/slurm/cluster run bash tests/slurm/run.sh; \
	rc=$$?; [ $$rc != 124 ] || echo "FAIL slurm: make test-slurm did not end in $(SLURM_TEST_TIMEOUT) s: stopped, the cluster torn down"; exit $$rc

# The stiff and extreme cases alone (docs/extreme-cases.md; tests/run's pattern also selects
# any unit test named for them); `make test` runs them too.
test-extreme: check-deps
	$(Q)$(MAKE) --no-print-directory all $(UNIT) $(TESTGEN) $(EXRDUMP)
	$(Q)BIN=$(abspath $(BIN)) BUILD=$(abspath $(BUILD)) bash tests/run extreme

asan:
	$(Q)$(MAKE) --no-print-directory BUILD=build/asan BIN=build/asan/bin CFLAGS="-O1 -g" \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer" all

test-asan:
	$(Q)ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
	    $(MAKE) --no-print-directory BUILD=build/asan BIN=build/asan/bin CFLAGS="-O1 -g" \
	    SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer" test-run

# ---- demo, bench, fuzz ----
demo: check-deps
	$(Q)$(MAKE) --no-print-directory all
	$(Q)BIN=$(abspath $(BIN)) bash pipelines/demo

bench: check-deps
	$(Q)$(MAKE) --no-print-directory all $(TESTGEN)
	$(Q)BIN=$(abspath $(BIN)) BUILD=$(abspath $(BUILD)) bash tests/bench/run $(BENCH)

# The same sections on smaller inputs and 3 runs each, in under two minutes.
bench-quick: check-deps
	$(Q)$(MAKE) --no-print-directory all $(TESTGEN)
	$(Q)QUICK=1 RUNS=3 N=200000 BIN=$(abspath $(BIN)) BUILD=$(abspath $(BUILD)) bash tests/bench/run $(BENCH)

# libFuzzer needs clang; Debian 12's is 14. The library is built with it as it is (the half
# conversion and the ISA sections have clang forms); a target links what it uses of it.
# Targets whose name is in FUZZ_RESEAL mutate past the checksum (tests/fuzz/reseal.h), each
# seeded with the golden files of its format; the image decoders' (fuzz_img_*) by
# tests/fuzz/image-seeds.sh. FUZZ=name... runs only those; FUZZ_SECONDS
# each (default 60); the corpus grows in build/fuzz/corpus-NAME, crashes land in build/fuzz.
FUZZ_DEBS := clang
FUZZ_TARGETS := $(basename $(notdir $(wildcard tests/fuzz/fuzz_*.c)))
FUZZ ?= $(FUZZ_TARGETS)
FUZZ_SAN := -fsanitize=address,undefined -fno-sanitize-recover=undefined
fuzz:
	@sh tests/install-deps.sh $(FUZZ_DEBS)
	$(Q)$(MAKE) --no-print-directory BUILD=build/fuzz BIN=build/fuzz/bin CC=clang CFLAGS="-O1 -g" WERROR= \
	    SAN="-fsanitize=fuzzer-no-link $(FUZZ_SAN)" build/fuzz/libpmtk.a
	$(Q)for t in $(FUZZ); do \
	    clang -std=c17 -D_GNU_SOURCE $(INCLUDES) -O1 -g -fsanitize=fuzzer $(FUZZ_SAN) -fopenmp -pthread \
	        $(PKG_CFLAGS) $(EMBREE_CFLAGS) tests/fuzz/$$t.c build/fuzz/libpmtk.a $(LIBS) -o build/fuzz/$$t || exit 1; \
	    seeds=build/fuzz/seeds-$$t; rm -rf $$seeds; mkdir -p $$seeds build/fuzz/corpus-$$t; \
	    case $$t in \
	    fuzz_scene) cp scenes/cornell-box/scene.json $$seeds/ ;; \
	    fuzz_scene_cache) ;; \
	    fuzz_img_*) bash tests/fuzz/image-seeds.sh $${t#fuzz_img_} $$seeds ;; \
	    fuzz_mesh_header) cp /usr/share/assimp/models/PLY/*.ply /usr/share/assimp/models/OFF/*.off \
	        /usr/share/assimp/models/STL/*.stl /usr/share/assimp/models/invalid/OutOfMemory.off tests/fuzz/meshes/* $$seeds/ ;; \
	    fuzz_photonmap|fuzz_queries|fuzz_radiance) \
	        for f in tests/golden/*.pm; do \
	            head -c 200 $$f | grep -qx "FORMAT=$${t#fuzz_}" && cp $$f $$seeds/; \
	        done ;; \
	    *) cp tests/golden/*.pm $$seeds/ ;; \
	    esac; \
	    echo "  FUZZ    $$t ($${FUZZ_SECONDS:-60} s)"; \
	    build/fuzz/$$t -max_total_time=$${FUZZ_SECONDS:-60} -print_final_stats=1 \
	        -artifact_prefix=build/fuzz/$$t- build/fuzz/corpus-$$t $$seeds || exit 1; \
	done

deps:
	@sh tests/install-deps.sh $(DEBS)

clean:
	rm -rf $(BUILD) $(BIN) $(ATRIUM_OBJ) scenes/atrium/atrium.mtl $(ATRIUM_SKY) $(CAUSTIC_OBJ) scenes/caustic/caustic.mtl

-include $(LIB_OBJ:.o=.d) $(UNIT_OBJ:.o=.d) $(STAGES:%=$(BUILD)/stages/%/main.d) $(BUILD)/tests/pm-testgen.d $(BUILD)/tests/pm-exrdump.d
