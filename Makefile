# seamtex - one non-recursive Makefile for the whole tree.
#
#   make            libraries, daemon, client, tools
#   make test       unit + integration tests and a bounded fuzz slice, in parallel (tests/run.sh);
#                   ends with "N passed, N failed"
#   make fuzz       a real fuzz campaign: every target FUZZ_SECONDS (600), corpora kept in
#                   build/fuzz-corpus/
#   make soak       the long SIGKILL soaks: SEAMTEX_SOAK_SECONDS (600) of durability rounds
#                   and 20 cluster kill/restart rounds (SEAMTEX_SOAK_ROUNDS)
#   make python     the Python module seamtex into build/python/ (also part of make all when
#                   python3-dev is installed; docs/python.md)
#   make bench      every benchmark; figures printed and written to build/bench/*.json
#   make ptex-compare PTEX_PREFIX=DIR   seamtex against a Ptex build of your own, every cell
#   make run        the main job: daemon on loopback, default data set, a query, a short load test
#   make asan       the tests again under AddressSanitizer + UBSan (build-san/)
#   make tsan       the daemon and client tests (tests/integration/) under ThreadSanitizer, the
#                   daemon and CLI built with it too (build-tsan/); suppressions in tests/tsan.supp
#   make install    PREFIX=/usr/local DESTDIR= (LIBDIR, MANDIR, ...): programs, libseamtex.a, the header, seamtex.pc, man
#                   pages (man/), the systemd unit, an example config (SYSCONFDIR, UNITDIR below)
#   make deb        build/seamtex_<version>_<arch>.deb from make install (deploy/build-deb.sh)
#   make check-man  the man pages lint-clean and true to --help and client/seamtex.h (in make test)
#   make check-deb  builds the .deb, lists it, lintian, extracts it and runs it (in make test)
#
# Dependencies are Debian packages; `make deps` (a prerequisite of test, bench and run) installs
# whatever is missing through deploy/install-deps.sh.
#
# Layout of the build: the dependency rules between folders are written down in
# store/README.md and ARCHITECTURE.md and enforced here: every object is compiled with the
# include paths of its own folder and of the folders it may depend on, and nothing else, so an
# include across a forbidden edge fails to compile.
#
#   util/            libseamtex_util.a   libc only
#   protocol/        libseamtex_proto.a  libc only
#   store/<part>/    libst_<part>.a      util + the store parts listed in STORE_DEPS_<part>
#                                        (+ STORE_EXT_<part>: service/ takes protocol/stp_name.h)
#   cluster/         libseamtex_cluster.a protocol + libseamtex's installed header + libcurl,
#                                        json-c (cluster/module.mk)
#   client/, server/, tests/, tools/     describe their own targets in their module.mk

CC       ?= gcc
CXX      ?= g++
PREFIX   ?= /usr/local
DESTDIR  ?=
# PREFIX=/usr (a package) puts the config under /etc and the unit where Debian keeps units
SYSCONFDIR ?= $(if $(filter /usr,$(PREFIX)),/etc,$(PREFIX)/etc)
UNITDIR    ?= $(if $(filter /usr,$(PREFIX)),/lib/systemd/system,$(PREFIX)/lib/systemd/system)
LIBDIR     ?= $(PREFIX)/lib
MANDIR     ?= $(PREFIX)/share/man
DOCDIR     ?= $(PREFIX)/share/doc/seamtex
SAN      ?= 0
NPROC    := $(shell nproc 2>/dev/null || echo 2)

ifeq ($(SAN),1)
B        := build-san
SANFLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
OPT      := -O1
else ifeq ($(SAN),tsan)
B        := build-tsan
SANFLAGS := -fsanitize=thread -fno-omit-frame-pointer
OPT      := -O1
else
B        := build
SANFLAGS :=
OPT      := -O2
endif

PKGS      := OpenImageIO OpenEXR zlib libdeflate
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS   := $(shell pkg-config --libs $(PKGS) 2>/dev/null)

WARN     := -Wall -Wextra -Werror
CPPFLAGS += -D_GNU_SOURCE -MMD -MP
# -ffp-contract=off: no a * b + c fused into one rounding unless the source asks for it (an
# fma intrinsic). The Ptex filters' AVX2 paths must give the portable paths' bits
# (test_ptexfilter_paths); gcc in -std=c11 already contracts nothing, but clang fuses within
# an expression wherever FMA is enabled (the "avx2,fma" functions, -march=native).
CFLAGS   := -std=c11 $(OPT) -g $(WARN) -ffp-contract=off -fPIC -pthread $(SANFLAGS) $(EXTRA_CFLAGS)
CXXFLAGS := -std=c++17 $(OPT) -g $(WARN) -fPIC -pthread $(SANFLAGS) $(PKG_CFLAGS) $(EXTRA_CFLAGS)
LDFLAGS  += -pthread $(SANFLAGS)
LDLIBS   := $(PKG_LIBS) -ldraco -lz -lm -lstdc++ -lpthread

# ---- util/ and protocol/: libc only ---------------------------------------------------------
UTIL_OBJ  := $(patsubst %.c,$(B)/%.o,$(sort $(wildcard util/*.c)))
PROTO_OBJ := $(patsubst %.c,$(B)/%.o,$(sort $(wildcard protocol/*.c)))
LIB_UTIL  := $(B)/libseamtex_util.a
LIB_PROTO := $(B)/libseamtex_proto.a
INC_util     := -Iutil
INC_protocol := -Iprotocol
$(B)/util/%.o:     MODINC := $(INC_util)
$(B)/protocol/%.o: MODINC := $(INC_protocol)

# ---- store/: one archive per part; the allowed edges, lowest part first ---------------------
# A part may include its own headers, util/'s and those of the parts named here (the list is
# closed under dependency: a part lists its dependencies' dependencies too).
STORE_PARTS      := core mesh sample ptex kinds bc1 import native service
STORE_DEPS_core    :=
STORE_DEPS_mesh    := core
STORE_DEPS_sample  := core
STORE_DEPS_ptex    := core sample
STORE_DEPS_kinds   := core mesh sample
STORE_DEPS_bc1     := core mesh sample kinds
STORE_DEPS_import  := core mesh sample ptex kinds bc1
STORE_DEPS_native  := core mesh sample ptex kinds
STORE_DEPS_service := core mesh sample ptex kinds bc1 import native
# outside the store: every part may use util/; service/ also takes the set-name rule from
# protocol/stp_name.h (header only: the registry and the wire apply one rule)
STORE_EXT_service  := $(INC_protocol)

store_inc = -Istore/$(1) $(foreach d,$(STORE_DEPS_$(1)),-Istore/$(d)) $(INC_util) $(STORE_EXT_$(1))
store_src = $(sort $(wildcard store/$(1)/*.c store/$(1)/*.cpp))
store_obj = $(patsubst %.cpp,$(B)/%.o,$(patsubst %.c,$(B)/%.o,$(call store_src,$(1))))

define STORE_PART
INC_store_$(1) := $$(call store_inc,$(1))
$(B)/store/$(1)/%.o: MODINC := $$(INC_store_$(1))
LIB_STORE_$(1) := $(B)/libst_$(1).a
$$(LIB_STORE_$(1)): $$(call store_obj,$(1))
	@mkdir -p $$(@D)
	rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach p,$(STORE_PARTS),$(eval $(call STORE_PART,$(p))))

STORE_C   := $(foreach p,$(STORE_PARTS),$(wildcard store/$(p)/*.c))
STORE_CXX := $(foreach p,$(STORE_PARTS),$(wildcard store/$(p)/*.cpp))
# every store part (highest first, the link order) and util: what links "the whole store"
LIB_STORE := $(foreach p,service native import bc1 kinds ptex sample mesh core,$(LIB_STORE_$(p))) $(LIB_UTIL)
# the include paths of the whole store (for the daemon, tests, tools)
INC_STORE := $(foreach p,$(STORE_PARTS),-Istore/$(p)) $(INC_util) $(INC_protocol)

all: $(LIB_STORE) $(LIB_PROTO) $(LIB_UTIL)

$(LIB_UTIL): $(UTIL_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(LIB_PROTO): $(PROTO_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(B)/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(MODINC) $(CFLAGS) -c $< -o $@

$(B)/%.o: %.cpp
	@mkdir -p $(@D)
	$(CXX) $(CPPFLAGS) $(MODINC) $(CXXFLAGS) -c $< -o $@

# ---- modules ------------------------------------------------------------------------------
# Each module.mk appends to ALL_BINS, TEST_BINS, BENCH_BINS, INSTALL_BINS and defines its rules.
ALL_BINS     :=
TEST_BINS    :=
BENCH_BINS   :=
INSTALL_BINS :=
INSTALL_LIBS :=
INSTALL_HDRS :=
-include protocol/module.mk
-include cluster/module.mk
-include client/module.mk
-include server/module.mk
-include tools/module.mk
-include python/module.mk
-include render/module.mk
include tests/module.mk

all: $(ALL_BINS)

# ---- top-level jobs --------------------------------------------------------------------------
deps:
	@bash deploy/install-deps.sh

test: deps
	@$(MAKE) --no-print-directory -j$(NPROC) all tests-build
	@$(MAKE) --no-print-directory check-layout check-man check-deploy
	@B=$(B) bash tests/run.sh; rc=$$?; $(if $(filter 0,$(SAN)),$(MAKE) --no-print-directory \
		check-deb || rc=1;) exit $$rc

# FUZZ_SECONDS per target (default 600); FUZZ_CORPUS_DIR keeps the corpora between campaigns.
fuzz: deps
	@$(MAKE) --no-print-directory -j$(NPROC) fuzz-build
	@B=$(B) MODE=fuzz FUZZ_SECONDS=$${FUZZ_SECONDS:-600} TEST_JOBS=$${TEST_JOBS:-$(NPROC)} \
		FUZZ_CORPUS_DIR=$${FUZZ_CORPUS_DIR:-$(CURDIR)/$(B)/fuzz-corpus} bash tests/run.sh

# SEAMTEX_SOAK_SECONDS of SIGKILL rounds (default 600), at least SEAMTEX_SOAK_ROUNDS (default 4);
# the cluster soak: SEAMTEX_SOAK_ROUNDS rounds, 20 by default (tests/run.sh MODE=soak).
soak: deps
	@$(MAKE) --no-print-directory -j$(NPROC) all tests-build
	@B=$(B) MODE=soak SEAMTEX_SOAK_SECONDS=$${SEAMTEX_SOAK_SECONDS:-600} \
		TEST_TIMEOUT=$${TEST_TIMEOUT:-$$(( $${SEAMTEX_SOAK_SECONDS:-600} + 600 ))} bash tests/run.sh

bench: deps
	@$(MAKE) --no-print-directory -j$(NPROC) all bench-build
	@B=$(B) bash tests/bench/run.sh

run: deps
	@$(MAKE) --no-print-directory -j$(NPROC) all
	@B=$(B) bash deploy/run-main.sh

# seamtex against the Ptex library, cell by cell (tests/bench/ptex_compare.py; docs/ptex.md
# "Against the Ptex library"). Ptex is not in Debian and never part of this repository:
# PTEX_PREFIX names a Ptex you built (PTEX_PREFIX/include/Ptexture.h, PTEX_PREFIX/lib/libPtex.*);
# PTEX_COMPARE_ARGS adds the script's options (--files, --fp, --rounds, ...).
ptex-compare: deps
	@test -n "$(PTEX_PREFIX)" || { echo "make ptex-compare PTEX_PREFIX=DIR (a Ptex build)"; exit 2; }
	@$(MAKE) --no-print-directory -j$(NPROC) all bench-build
	@mkdir -p $(B)/ptexcmp
	$(CXX) -std=c++11 -O2 -Wall -Wextra -I$(PTEX_PREFIX)/include tests/bench/ptexcmp/ptexq.cpp \
		-L$(PTEX_PREFIX)/lib -Wl,-rpath,$(PTEX_PREFIX)/lib -lPtex -lz -lpthread -o $(B)/ptexcmp/ptexq
	$(CXX) -std=c++11 -O2 -Wall -Wextra -I$(PTEX_PREFIX)/include tests/bench/ptexcmp/ptexopen.cpp \
		-L$(PTEX_PREFIX)/lib -Wl,-rpath,$(PTEX_PREFIX)/lib -lPtex -lz -lpthread -o $(B)/ptexcmp/ptexopen
	python3 tests/bench/ptex_compare.py --ptexq $(B)/ptexcmp/ptexq --ptexopen $(B)/ptexcmp/ptexopen \
		--bench $(B)/bench/bench_ptex --json $(B)/bench/ptex_compare.json $(PTEX_COMPARE_ARGS)

# a daemon under ASan starts several times slower: as make tsan, give starts more time
asan:
	@SEAMTEX_START_MS=$${SEAMTEX_START_MS:-180000} $(MAKE) --no-print-directory SAN=1 test

# Every test that starts seamtexd (tests/integration/: server, client, CLI, durability) with the
# tests, the daemon and the CLI built with -fsanitize=thread; every process's reports go to
# build-tsan/test-logs/tsan.<pid> and any report fails the run (tests/run.sh, MODE=tsan).
tsan: deps
	@$(MAKE) --no-print-directory SAN=tsan -j$(NPROC) all tsan-build
	@B=build-tsan MODE=tsan SEAMTEX_START_MS=$${SEAMTEX_START_MS:-180000} bash tests/run.sh

# The unit and the example config name /usr/local/bin and /etc/seamtex; both follow PREFIX and
# SYSCONFDIR here. The config is installed only where none exists (an edited one is kept).
MAN_PAGES := $(sort $(wildcard man/*.[1-8]))
install: all
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(LIBDIR) $(DESTDIR)$(PREFIX)/include/seamtex \
		$(DESTDIR)$(LIBDIR)/pkgconfig $(DESTDIR)$(UNITDIR) $(DESTDIR)$(DOCDIR)/examples \
		$(DESTDIR)$(SYSCONFDIR)/seamtex \
		$(sort $(foreach m,$(MAN_PAGES),$(DESTDIR)$(MANDIR)/man$(subst .,,$(suffix $(m)))))
	$(if $(INSTALL_BINS),install -m 755 $(INSTALL_BINS) $(DESTDIR)$(PREFIX)/bin/)
	$(if $(INSTALL_LIBS),install -m 644 $(INSTALL_LIBS) $(DESTDIR)$(LIBDIR)/)
	$(if $(INSTALL_HDRS),install -m 644 $(INSTALL_HDRS) $(DESTDIR)$(PREFIX)/include/seamtex/)
	@for pc in client/*.pc.in; do [ -f "$$pc" ] || continue; \
		sed -e 's|@PREFIX@|$(PREFIX)|g' -e 's|@LIBDIR@|$(LIBDIR)|g' "$$pc" \
		> $(DESTDIR)$(LIBDIR)/pkgconfig/$$(basename "$$pc" .in); done
	$(foreach m,$(MAN_PAGES),install -m 644 $(m) $(DESTDIR)$(MANDIR)/man$(subst .,,$(suffix $(m)))/ &&) true
	sed -e 's|/usr/local/bin/|$(PREFIX)/bin/|g' -e 's|/usr/local/share/doc/seamtex|$(DOCDIR)|g' \
		-e 's|/etc/seamtex|$(SYSCONFDIR)/seamtex|g' deploy/seamtexd.service \
		> $(DESTDIR)$(UNITDIR)/seamtexd.service && chmod 644 $(DESTDIR)$(UNITDIR)/seamtexd.service
	sed -e 's|/etc/seamtex|$(SYSCONFDIR)/seamtex|g' deploy/seamtexd.conf.example \
		> $(DESTDIR)$(DOCDIR)/examples/seamtexd.conf.example
	chmod 644 $(DESTDIR)$(DOCDIR)/examples/seamtexd.conf.example
	install -m 644 README.md $(DESTDIR)$(DOCDIR)/README.md
	[ -e $(DESTDIR)$(SYSCONFDIR)/seamtex/seamtexd.conf ] || install -m 644 \
		$(DESTDIR)$(DOCDIR)/examples/seamtexd.conf.example $(DESTDIR)$(SYSCONFDIR)/seamtex/seamtexd.conf

# A Debian package from `make install DESTDIR=<staging> PREFIX=/usr` (deploy/build-deb.sh):
# $(B)/seamtex_<version>_<arch>.deb.
deb: all
	@B=$(B) bash deploy/build-deb.sh

# The man pages: mandoc -Tlint -Wwarning clean, every flag / command / option / stc_ function
# of the programs and client/seamtex.h documented, and a self-test that the check catches a
# page with one taken out (tests/check_man.py).
check-man: all
	@python3 tests/check_man.py man $(B)

# The package: built, its file list checked, lintian (overrides with reasons in
# deploy/lintian-overrides), extracted into a scratch root where its programs run
# (tests/check-deb.sh; never installed into this system). Packages the normal build, so
# make test runs it only when SAN=0 (make asan would otherwise build build/ as well).
check-deb: all
	@B=$(B) bash tests/check-deb.sh

# deploy/: the Kubernetes manifests parse and every seamtexd flag deploy/ uses is one that
# `seamtexd --help` lists (deploy/check-deploy.py says which flags may still be missing).
check-deploy: $(B)/seamtexd $(B)/seamtex
	@python3 deploy/check-deploy.py $(B)/seamtexd $(B)/seamtex

# Every store part's headers compile on their own with only the include paths the rules above
# give that part (no header leans on what an including file happened to include first).
check-layout:
	@$(foreach p,$(STORE_PARTS),$(foreach h,$(wildcard store/$(p)/*.h),\
		echo '#include "$(notdir $(h))"' | $(CC) -std=c11 -D_GNU_SOURCE $(PKG_CFLAGS) -fsyntax-only \
		$(INC_store_$(p)) -x c - || exit 1;)) echo "check-layout: every store header compiles alone"
	@! grep -rn '#include "\(\.\./\|/\)' store protocol util client server \
		|| { echo "check-layout: an include by relative or absolute path bypasses the rules"; exit 1; }
	@echo "check-layout: no include by path in store/ protocol/ util/ client/ server/"

clean:
	rm -rf build build-san build-tsan

.PHONY: all deps test fuzz soak bench ptex-compare run asan tsan install clean tests-build fuzz-build bench-build \
	tsan-build check-layout check-deploy python deb check-man check-deb

-include $(shell find $(B) -name '*.d' 2>/dev/null)
