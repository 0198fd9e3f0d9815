# simcluster - one plain Makefile (see README.md).
#   make            library (static + shared), examples, tools
#   make check      every test, then again under ASan+UBSan, man lint, install test
#   make demo       the main job (embedded default)
#   make bench      benchmarks (bench/results.sh -> bench/RESULTS.md; BENCH_FLAGS=-q: smoke run)
#   make bench-raw  every benchmark with its defaults, tables to stdout
#   make install PREFIX=/usr/local DESTDIR=   (SYSTEMDDIR: the systemd unit)
#   make V=1        show commands;  make SAN=1  sanitizer build (in build-san/)
#   make WERROR=-Werror   warnings are errors (make check and CI build this way;
#                   a plain make does not, so a newer compiler's new warning
#                   does not stop a packager's build)

# plain `make` builds everything a user runs (the first rule below would
# otherwise be the warnings stamp)
.DEFAULT_GOAL := all

PREFIX  ?= /usr/local
DESTDIR ?=
LIBDIR  ?= $(PREFIX)/lib
INCDIR  ?= $(PREFIX)/include
BINDIR  ?= $(PREFIX)/bin
SBINDIR ?= $(PREFIX)/sbin
MANDIR  ?= $(PREFIX)/share/man
SYSTEMDDIR ?= $(PREFIX)/lib/systemd/system
PCDIR   ?= $(LIBDIR)/pkgconfig

VERSION := 0.1.0
SOMAJOR := 0

CC      ?= cc
WERROR  ?=
SANFLAGS := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
# -O3 for the build that runs (3-7 % faster on the 1000-part drop than -O2,
# the same bits); the sanitizer build stays at -O2, which compiles faster
# (make check builds both)
ifeq ($(SAN),1)
BUILD   ?= build-san
XFLAGS  := $(SANFLAGS)
OPT     ?= -O2
else
BUILD   ?= build
XFLAGS  :=
OPT     ?= -O3
endif

# KLU (SuiteSparse) factors big islands (island_sparse.c); Debian ships no
# pkg-config file for it.
SUITESPARSE_INC := -I/usr/include/suitesparse
SUITESPARSE_LIBS := -lklu
DEP_PKGS := ode ccd gsl lcm libsodium
GEN     := $(BUILD)/gen
# The library's layers, each seeing only its own and lower layers' headers
# (docs/DESIGN.md section 2): core <- exec <- net <- api.
LAYERS  := core exec net api
INC_core := -Ilib/core $(SUITESPARSE_INC)
INC_exec := $(INC_core) -Ilib/exec
INC_net  := $(INC_exec) -Ilib/net -I$(GEN)
INC_api  := $(INC_net) -Ilib/api
CPPFLAGS += -Iinclude -D_GNU_SOURCE
# Programs and tests see the public headers only, unless they name a layer
# (internal tests: LAYER_<name> := core, exec, net or api).
LAYER_test_arena := core
LAYER_test_broadphase := core
LAYER_test_hull := core
LAYER_test_island := core
LAYER_test_island_schur := core
LAYER_test_lcp := core
LAYER_test_shape_load := core
LAYER_test_units := api
LAYER_test_contact := api
LAYER_test_toi := core
LAYER_test_ccd := core
LAYER_test_cluster_msg := net
LAYER_test_bus := net
LAYER_test_unit_wire := api
LAYER_test_compute := net
LAYER_test_idle := core
LAYER_test_narrowphase := core
LAYER_test_cluster := api
LAYER_bench_broadphase := core
LAYER_bench_lcp := core
LAYER_bench_toi := core
LAYER_bench_pieces := core
LAYER_bench_cluster := api
LAYER_bench_drop := core
LAYER_bench_islands := api
LAYER_fuzz_envelope := net
LAYER_fuzz_bus := net
LAYER_cluster_inject := net
LAYER_fuzz_load := core
# Programs (tools, the daemon, examples) see only the public headers;
# tests and benchmarks may also include the daemon's own (-Idaemon).
PROG_CPPFLAGS := -Iinclude -D_GNU_SOURCE
CFLAGS  += -std=c11 $(OPT) -g -Wall -Wextra $(WERROR) -fPIC -fvisibility=hidden \
           -pthread $(XFLAGS)
LDFLAGS += -pthread $(XFLAGS)
LIBS    := $(shell pkg-config --libs $(DEP_PKGS) 2>/dev/null || \
             echo -lode -lccd -lgsl -lgslcblas -llcm -lsodium) $(SUITESPARSE_LIBS) -lm -ldl
TESTLIBS := $(LIBS) -lcmocka
# simcluster-view(1) renders with OSMesa and writes PNG; tests/png_check reads PNG.
PNG_LIBS := $(shell pkg-config --cflags --libs libpng 2>/dev/null || echo -lpng)
TOOL_LIBS_simcluster-view := $(shell pkg-config --cflags --libs osmesa 2>/dev/null || \
             echo -lOSMesa) $(PNG_LIBS)

# Objects built without WERROR may hold warnings: a WERROR build depends on
# $(BUILD)/werror.stamp, which any build without it removes, so make check
# after a plain make compiles everything again, with -Werror.
WSTAMP  := $(BUILD)/werror.stamp
WDEP    := $(if $(WERROR),$(WSTAMP))
WFORGET := $(if $(WERROR),:,rm -f $(WSTAMP))
$(WSTAMP):
	@mkdir -p $(dir $@)
	@touch $@

ifeq ($(V),1)
Q :=
else
Q := @
endif

LIB_SRC   := $(sort $(foreach l,$(LAYERS),$(wildcard lib/$(l)/*.c)))
LIB_HDR   := $(wildcard include/*.h lib/*.h lib/*/*.h)
# Message types: C generated from proto/*.lcm by lcm-gen into $(GEN)/ (one
# sclcm_<struct>.c/.h per struct), linked into the library, never committed.
PROTO     := $(sort $(wildcard proto/*.lcm))
GEN_NAMES := $(shell sed -n 's/^struct  *\([A-Za-z0-9_]*\).*/sclcm_\1/p' $(PROTO))
GEN_SRC   := $(GEN_NAMES:%=$(GEN)/%.c)
GEN_OBJ   := $(GEN_SRC:.c=.o)
LIB_OBJ   := $(LIB_SRC:%.c=$(BUILD)/%.o) $(GEN_OBJ)
TEST_SRC  := $(sort $(wildcard tests/test_*.c))
TEST_BIN  := $(TEST_SRC:%.c=$(BUILD)/%)
EX_SRC    := $(sort $(wildcard examples/*.c))
EX_BIN    := $(EX_SRC:%.c=$(BUILD)/%)
TOOL_SRC  := $(sort $(wildcard tools/*.c))
TOOL_BIN  := $(TOOL_SRC:tools/%.c=$(BUILD)/tools/%)
DAEMON_SRC := $(sort $(wildcard daemon/*.c))
DAEMON_BIN := $(if $(DAEMON_SRC),$(BUILD)/daemon/simclusterd)
# The daemon's engine (everything but its main), also linked into the tests
# and benchmarks that start daemons in-process.
DAEMON_LIB_SRC := $(filter-out daemon/simclusterd.c,$(DAEMON_SRC))
DAEMON_LIB := $(BUILD)/daemon/libscd.a
DAEMON_HDR := $(wildcard daemon/*.h)
BENCH_SRC := $(sort $(wildcard bench/*.c))
BENCH_BIN := $(BENCH_SRC:%.c=$(BUILD)/%)
# Conservative advancement (extra/ca/, docs/DESIGN.md 3.4): not in the
# library; linked into the test and the benchmark that compare it with the
# library's sampling search.
CA_SRC    := $(sort $(wildcard extra/ca/*.c))
CA_OBJ    := $(CA_SRC:%.c=$(BUILD)/%.o)
CA_USERS  := $(BUILD)/tests/test_ccd $(BUILD)/bench/bench_toi
FUZZ_SRC  := $(sort $(wildcard tests/fuzz/fuzz_*.c))
FUZZ_REPLAY := $(FUZZ_SRC:tests/fuzz/%.c=$(BUILD)/tests/fuzz/%_replay)
# Programs tests/cluster.sh drives (not test_*: run.sh does not run them itself).
CLUSTER_BIN := $(BUILD)/tests/cluster_run $(BUILD)/tests/cluster_inject
# The pixel checker tests/view.sh uses (both builds).
VIEW_BIN  := $(BUILD)/tests/png_check

STATIC := $(BUILD)/libsimcluster.a
SHARED := $(BUILD)/libsimcluster.so.$(VERSION)

.PHONY: all lib deps check check-run demo bench bench-raw install uninstall clean lint-man test-install fuzz
all: lib $(EX_BIN) $(TOOL_BIN) $(DAEMON_BIN) $(BENCH_BIN)
lib: $(STATIC) $(SHARED)

deps:
	$(Q)sh scripts/deps.sh

$(foreach l,$(LAYERS),$(eval $(BUILD)/lib/$(l)/%.o: LAYER_INC := $(INC_$(l))))
$(BUILD)/extra/ca/%.o: LAYER_INC := $(INC_core)
$(CA_OBJ): extra/ca/ca.h
$(CA_USERS): $(CA_OBJ) extra/ca/ca.h
$(CA_USERS): private EXTRA_CPPFLAGS := -Iextra/ca
$(CA_USERS): private EXTRA_OBJ := $(CA_OBJ)
$(BUILD)/%.o: %.c $(LIB_HDR) Makefile $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(CPPFLAGS) $(LAYER_INC) $(CFLAGS) -c $< -o $@

# --c-no-pubsub: messages go out as sealed bytes through lcm_publish
# (lib/cluster_msg.c), and the generated subscribe stubs print to stderr.
$(GEN)/stamp: $(PROTO) Makefile
	@mkdir -p $(GEN)
	@$(if $(Q),echo "  LCMGEN  $(PROTO)")
	$(Q)rm -f $(GEN)/sclcm_*
	$(Q)lcm-gen -c --c-no-pubsub --c-cpath $(GEN) --c-hpath $(GEN) $(PROTO)
	$(Q)touch $@
$(GEN_SRC): $(GEN)/stamp ;

# Generated headers exist before any library object is compiled.
$(filter $(BUILD)/lib/%,$(LIB_OBJ)): | $(GEN)/stamp
$(BUILD)/lib/net/cluster_msg.o $(BUILD)/lib/net/frame_record.o: $(GEN)/stamp

# lcm-gen's cleanup functions for types without arrays or strings do not
# use their argument: -Wno-unused-parameter, for these files only.
$(GEN)/%.o: $(GEN)/%.c $(GEN)/stamp $(WDEP)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(CPPFLAGS) $(INC_net) $(CFLAGS) -Wno-unused-parameter -c $< -o $@

$(STATIC): $(LIB_OBJ)
	@$(if $(Q),echo "  AR      $@")
	$(Q)rm -f $@ && ar rcs $@ $^

$(SHARED): $(LIB_OBJ)
	@$(if $(Q),echo "  LD      $@")
	$(Q)$(CC) -shared -Wl,-soname,libsimcluster.so.$(SOMAJOR) -Wl,--no-undefined \
	    $(LDFLAGS) -o $@ $^ $(LIBS)
	$(Q)ln -sf libsimcluster.so.$(VERSION) $(BUILD)/libsimcluster.so.$(SOMAJOR)
	$(Q)ln -sf libsimcluster.so.$(SOMAJOR) $(BUILD)/libsimcluster.so

# Tests link the static library and the daemon's engine (internal tests
# name their layer above, LAYER_<name>; any may include daemon/*.h).
$(BUILD)/tests/%: tests/%.c $(wildcard tests/*.h) $(DAEMON_LIB) $(STATIC) $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  TEST    $@")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(CPPFLAGS) $(INC_$(LAYER_$(notdir $*))) $(EXTRA_CPPFLAGS) -Idaemon $(CFLAGS) $< -o $@ \
	    $(LDFLAGS) $(EXTRA_OBJ) $(DAEMON_LIB) $(STATIC) $(TESTLIBS)

$(BUILD)/examples/%: examples/%.c include/simcluster.h $(STATIC) $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  EXAMPLE $@")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(PROG_CPPFLAGS) $(CFLAGS) $< -o $@ $(LDFLAGS) $(STATIC) $(LIBS)

$(BUILD)/tools/%: tools/%.c $(wildcard include/*.h) $(STATIC) Makefile $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  TOOL    $@")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(PROG_CPPFLAGS) $(CFLAGS) $< -o $@ $(LDFLAGS) $(STATIC) $(LIBS) $(TOOL_LIBS_$*)

$(BUILD)/tests/png_check: tests/png_check.c Makefile $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  TEST    $@")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(CFLAGS) $< -o $@ $(LDFLAGS) $(PNG_LIBS) -lm

# simclusterd(8): daemon/simclusterd.c (the process) and the engine, with
# the public headers only, like any program.
$(BUILD)/daemon/%.o: daemon/%.c $(DAEMON_HDR) $(wildcard include/*.h) Makefile $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(PROG_CPPFLAGS) $(CFLAGS) -c $< -o $@

$(DAEMON_LIB): $(DAEMON_LIB_SRC:%.c=$(BUILD)/%.o)
	@$(if $(Q),echo "  AR      $@")
	$(Q)rm -f $@ && ar rcs $@ $^

$(BUILD)/daemon/simclusterd: $(BUILD)/daemon/simclusterd.o $(DAEMON_LIB) $(STATIC)
	@$(if $(Q),echo "  DAEMON  $@")
	$(Q)$(CC) $(CFLAGS) $< -o $@ $(LDFLAGS) $(DAEMON_LIB) $(STATIC) $(LIBS)

$(BUILD)/bench/%: bench/%.c $(wildcard bench/*.h tests/canon.h) $(DAEMON_LIB) $(STATIC) $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  BENCH   $@")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(CPPFLAGS) $(INC_$(LAYER_$*)) $(EXTRA_CPPFLAGS) -Idaemon $(CFLAGS) $< -o $@ \
	    $(LDFLAGS) $(EXTRA_OBJ) $(DAEMON_LIB) $(STATIC) $(LIBS) -ldl

# Fuzz targets: a replay driver (every file of the corpus, run by make check)
# and, with clang, a libFuzzer binary (make fuzz).
$(BUILD)/tests/fuzz/%_replay: tests/fuzz/%.c tests/fuzz/replay_main.c $(STATIC) $(WDEP)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  FUZZ    $@")
	$(Q)$(WFORGET)
	$(Q)$(CC) $(CPPFLAGS) $(INC_$(LAYER_$*)) $(CFLAGS) $< tests/fuzz/replay_main.c -o $@ $(LDFLAGS) $(STATIC) $(LIBS)

FUZZ_TIME ?= 60
fuzz:
	$(Q)sh tests/fuzz/run.sh $(FUZZ_TIME)

# make check builds on every CPU unless given -j itself: its two builds
# (plain and sanitized) are most of its time.
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
JFLAG = $(if $(filter -j% j%,$(MAKEFLAGS)),,-j$(JOBS))
check: deps
	$(Q)$(MAKE) --no-print-directory $(JFLAG) WERROR=-Werror all $(TEST_BIN) $(FUZZ_REPLAY) $(CLUSTER_BIN) $(VIEW_BIN)
	$(Q)$(MAKE) --no-print-directory $(JFLAG) WERROR=-Werror SAN=1 lib $(TEST_BIN:$(BUILD)/%=build-san/%) $(FUZZ_REPLAY:$(BUILD)/%=build-san/%) \
	    $(TOOL_BIN:$(BUILD)/%=build-san/%) $(DAEMON_BIN:$(BUILD)/%=build-san/%) $(VIEW_BIN:$(BUILD)/%=build-san/%)
	$(Q)sh tests/run.sh $(BUILD) build-san

check-run: $(TEST_BIN) $(FUZZ_REPLAY) $(TOOL_BIN) $(DAEMON_BIN) $(CLUSTER_BIN) $(VIEW_BIN)
	$(Q)sh tests/run.sh $(BUILD)

demo: deps
	$(Q)$(MAKE) --no-print-directory $(BUILD)/examples/bolts_nuts
	$(Q)./$(BUILD)/examples/bolts_nuts 50

# bench/results.sh runs issue 7's parts and writes bench/RESULTS.md;
# bench-raw runs every benchmark with its defaults and prints the tables.
BENCH_FLAGS ?=
bench: all
	$(Q)BUILD=$(BUILD) sh bench/results.sh $(BENCH_FLAGS)

bench-raw: all
	$(Q)for b in $(BENCH_BIN); do echo "== $$b"; ./$$b || exit 1; done

lint-man:
	$(Q)for m in man/*.[1-8]; do mandoc -T lint -W warning $$m || exit 1; done

# written again whenever the install paths differ from the last ones (a
# .pc left from another PREFIX pointed programs at the wrong library)
PC_PATHS := $(PREFIX)|$(LIBDIR)|$(INCDIR)|$(VERSION)
ifneq ($(PC_PATHS),$(shell cat $(BUILD)/simcluster.pc.paths 2>/dev/null))
.PHONY: $(BUILD)/simcluster.pc
endif
$(BUILD)/simcluster.pc: simcluster.pc.in Makefile
	@mkdir -p $(BUILD)
	$(Q)sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@LIBDIR@|$(patsubst $(PREFIX)%,$${prefix}%,$(LIBDIR))|' \
	    -e 's|@INCDIR@|$(patsubst $(PREFIX)%,$${prefix}%,$(INCDIR))|' \
	    -e 's|@VERSION@|$(VERSION)|' $< > $(BUILD)/simcluster.pc
	$(Q)printf '%s\n' '$(PC_PATHS)' > $(BUILD)/simcluster.pc.paths

install: lib $(TOOL_BIN) $(DAEMON_BIN) $(BUILD)/simcluster.pc
	install -d $(DESTDIR)$(LIBDIR) $(DESTDIR)$(INCDIR) $(DESTDIR)$(PCDIR) $(DESTDIR)$(BINDIR)
	install -m 644 $(STATIC) $(DESTDIR)$(LIBDIR)/
	install -m 755 $(SHARED) $(DESTDIR)$(LIBDIR)/
	ln -sf libsimcluster.so.$(VERSION) $(DESTDIR)$(LIBDIR)/libsimcluster.so.$(SOMAJOR)
	ln -sf libsimcluster.so.$(SOMAJOR) $(DESTDIR)$(LIBDIR)/libsimcluster.so
	install -m 644 include/simcluster.h include/simcluster_net.h $(DESTDIR)$(INCDIR)/
	install -m 644 $(BUILD)/simcluster.pc $(DESTDIR)$(PCDIR)/
	$(if $(TOOL_BIN),install -m 755 $(TOOL_BIN) $(DESTDIR)$(BINDIR)/)
	$(if $(DAEMON_BIN),install -d $(DESTDIR)$(SBINDIR) && install -m 755 $(DAEMON_BIN) $(DESTDIR)$(SBINDIR)/)
	$(if $(DAEMON_BIN),install -d $(DESTDIR)$(SYSTEMDDIR) && \
	    sed 's|@SBINDIR@|$(SBINDIR)|g' daemon/simclusterd.service >$(DESTDIR)$(SYSTEMDDIR)/simclusterd.service && \
	    chmod 644 $(DESTDIR)$(SYSTEMDDIR)/simclusterd.service)
	for m in man/*.[1-8]; do s=$${m##*.}; install -d $(DESTDIR)$(MANDIR)/man$$s; \
	    install -m 644 $$m $(DESTDIR)$(MANDIR)/man$$s/; done

uninstall:
	rm -f $(DESTDIR)$(LIBDIR)/libsimcluster.* $(DESTDIR)$(INCDIR)/simcluster.h \
	      $(DESTDIR)$(INCDIR)/simcluster_net.h \
	      $(DESTDIR)$(PCDIR)/simcluster.pc $(DESTDIR)$(SBINDIR)/simclusterd \
	      $(TOOL_BIN:$(BUILD)/tools/%=$(DESTDIR)$(BINDIR)/%) $(DESTDIR)$(SYSTEMDDIR)/simclusterd.service
	for m in man/*.[1-8]; do rm -f $(DESTDIR)$(MANDIR)/man$${m##*.}/$${m##*/}; done

clean:
	rm -rf build build-san
