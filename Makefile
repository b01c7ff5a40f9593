# seamtex - one non-recursive Makefile for the whole tree.
#
#   make            libraries, daemon, client, tools
#   make test       unit + integration tests and a bounded fuzz slice, in parallel (tests/run.sh);
#                   ends with "N passed, N failed"
#   make fuzz       a real fuzz campaign: every target FUZZ_SECONDS (600), corpora kept in
#                   build/fuzz-corpus/
#   make soak       the long SIGKILL durability soak: SEAMTEX_SOAK_SECONDS (600) of rounds
#   make bench      every benchmark; figures printed and written to build/bench/*.json
#   make run        the main job: daemon on loopback, default data set, a query, a short load test
#   make asan       the tests again under AddressSanitizer + UBSan (build-san/)
#   make install    PREFIX=/usr/local DESTDIR=
#
# Dependencies are Debian packages; `make deps` (a prerequisite of test, bench and run) installs
# whatever is missing through deploy/install-deps.sh.
#
# Layout of the build: every store/*.c and store/*.cpp goes into libseamtex_store.a, protocol/*.c
# into libseamtex_proto.a; client/, server/ and tests/ describe their own targets in the
# module.mk beside their sources.

CC       ?= gcc
CXX      ?= g++
PREFIX   ?= /usr/local
DESTDIR  ?=
SAN      ?= 0
NPROC    := $(shell nproc 2>/dev/null || echo 2)

ifeq ($(SAN),1)
B        := build-san
SANFLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
OPT      := -O1
else
B        := build
SANFLAGS :=
OPT      := -O2
endif

PKGS      := OpenImageIO OpenEXR zlib
PKG_CFLAGS := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS   := $(shell pkg-config --libs $(PKGS) 2>/dev/null)

WARN     := -Wall -Wextra -Werror
CPPFLAGS += -D_GNU_SOURCE -Istore -Iprotocol -Iclient -MMD -MP
CFLAGS   := -std=c11 $(OPT) -g $(WARN) -fPIC -pthread $(SANFLAGS) $(EXTRA_CFLAGS)
CXXFLAGS := -std=c++17 $(OPT) -g $(WARN) -fPIC -pthread $(SANFLAGS) $(PKG_CFLAGS) $(EXTRA_CFLAGS)
LDFLAGS  += -pthread $(SANFLAGS)
LDLIBS   := $(PKG_LIBS) -ldraco -lz -lm -lstdc++ -lpthread

# ---- libraries --------------------------------------------------------------------------
STORE_C   := $(sort $(wildcard store/*.c))
STORE_CXX := $(sort $(wildcard store/*.cpp))
STORE_OBJ := $(STORE_C:%.c=$(B)/%.o) $(STORE_CXX:%.cpp=$(B)/%.o)
PROTO_OBJ := $(patsubst %.c,$(B)/%.o,$(sort $(wildcard protocol/*.c)))

LIB_STORE := $(B)/libseamtex_store.a
LIB_PROTO := $(B)/libseamtex_proto.a

all: $(LIB_STORE) $(LIB_PROTO)

$(LIB_STORE): $(STORE_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(LIB_PROTO): $(PROTO_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(B)/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c $< -o $@

$(B)/%.o: %.cpp
	@mkdir -p $(@D)
	$(CXX) $(CPPFLAGS) $(CXXFLAGS) -c $< -o $@

# ---- modules ------------------------------------------------------------------------------
# Each module.mk appends to ALL_BINS, TEST_BINS, BENCH_BINS, INSTALL_BINS and defines its rules.
ALL_BINS     :=
TEST_BINS    :=
BENCH_BINS   :=
INSTALL_BINS :=
INSTALL_LIBS :=
INSTALL_HDRS :=
-include protocol/module.mk
-include server/module.mk
-include client/module.mk
-include tools/module.mk
include tests/module.mk

all: $(ALL_BINS)

# ---- top-level jobs --------------------------------------------------------------------------
deps:
	@bash deploy/install-deps.sh

test: deps
	@$(MAKE) --no-print-directory -j$(NPROC) all tests-build
	@B=$(B) bash tests/run.sh

# FUZZ_SECONDS per target (default 600); FUZZ_CORPUS_DIR keeps the corpora between campaigns.
fuzz: deps
	@$(MAKE) --no-print-directory -j$(NPROC) fuzz-build
	@B=$(B) MODE=fuzz FUZZ_SECONDS=$${FUZZ_SECONDS:-600} TEST_JOBS=$${TEST_JOBS:-$(NPROC)} \
		FUZZ_CORPUS_DIR=$${FUZZ_CORPUS_DIR:-$(CURDIR)/$(B)/fuzz-corpus} bash tests/run.sh

# SEAMTEX_SOAK_SECONDS of SIGKILL rounds (default 600), at least SEAMTEX_SOAK_ROUNDS (default 4).
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

asan:
	@$(MAKE) --no-print-directory SAN=1 test

install: all
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib $(DESTDIR)$(PREFIX)/include/seamtex \
		$(DESTDIR)$(PREFIX)/lib/pkgconfig
	$(if $(INSTALL_BINS),install -m 755 $(INSTALL_BINS) $(DESTDIR)$(PREFIX)/bin/)
	$(if $(INSTALL_LIBS),install -m 644 $(INSTALL_LIBS) $(DESTDIR)$(PREFIX)/lib/)
	$(if $(INSTALL_HDRS),install -m 644 $(INSTALL_HDRS) $(DESTDIR)$(PREFIX)/include/seamtex/)
	@if [ -f client/seamtex.pc.in ]; then \
		sed -e 's|@PREFIX@|$(PREFIX)|g' client/seamtex.pc.in > $(DESTDIR)$(PREFIX)/lib/pkgconfig/seamtex.pc; fi

clean:
	rm -rf build build-san

.PHONY: all deps test fuzz soak bench run asan install clean tests-build fuzz-build bench-build

-include $(shell find $(B) -name '*.d' 2>/dev/null)
