# tests/module.mk - test, benchmark and fuzz targets (included by the top Makefile).
#
#   tests/unit/test_*.c         one cmocka binary each, linked with every library
#   tests/integration/test_*.c  the same, but they start seamtexd on loopback (any new
#                               test_*.c is built and run without listing it anywhere)
#   tests/common/*.c            helpers shared by tests and benchmarks (libtestutil.a): the
#                               daemon fixture, libseamtex and STATS helpers, raw frames,
#                               wait-until, in-memory .ptx files, shared-data paths
#   tests/bench/bench_*.c       benchmarks; tests/bench/run.sh runs them (make bench)
#   tests/fuzz/fuzz_*.c         libFuzzer targets built with clang
#
# tests/run.sh runs them all in parallel: make test (every binary, each fuzz target for
# FUZZ_SECONDS, default 8), make fuzz (fuzz targets only, 600 s each, corpora kept in
# $(B)/fuzz-corpus/), make soak (test_durability for SEAMTEX_SOAK_SECONDS, default 600, and
# test_cluster_soak for 20 kill/restart rounds).

# Tests see everything (they test every layer directly).
INC_TESTS := -Itests/common -Iclient -Iserver -Iprotocol -Irender $(INC_STORE)
$(B)/tests/%.o: MODINC := $(INC_TESTS)

# faultpreload.c is an LD_PRELOAD object (it defines write, open, ...): never in the archive
TESTUTIL_OBJ := $(filter-out $(B)/tests/common/faultpreload.o,\
                $(patsubst %.c,$(B)/%.o,$(sort $(wildcard tests/common/*.c))))
LIB_TESTUTIL := $(B)/libtestutil.a
$(LIB_TESTUTIL): $(TESTUTIL_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# LIB_CLIENT and LIB_SERVER come from client/module.mk and server/module.mk when they exist.
ST_LINK := $(LIB_TESTUTIL) $(LIB_RENDER) $(LIB_SERVER) $(LIB_CLUSTER) $(LIB_CLIENT) $(LIB_PROTO) $(LIB_STORE)

TEST_SRC  := $(sort $(wildcard tests/unit/test_*.c tests/integration/test_*.c))
TEST_BINS += $(patsubst tests/%.c,$(B)/tests/%,$(TEST_SRC))
BENCH_SRC := $(sort $(wildcard tests/bench/bench_*.c))
BENCH_BINS += $(patsubst tests/bench/%.c,$(B)/bench/%,$(BENCH_SRC))

# tests of cluster/'s decoders, and the tests that read or write etcd themselves, see its
# headers and json-c
$(B)/tests/unit/test_etcd_reply.o: MODINC := $(INC_TESTS) -Icluster $(CLUSTER_PKG_CFLAGS)
$(B)/tests/integration/test_cluster_doubt.o: MODINC := $(INC_TESTS) -Icluster $(CLUSTER_PKG_CFLAGS)
$(B)/tests/integration/test_cluster_publish.o: MODINC := $(INC_TESTS) -Icluster $(CLUSTER_PKG_CFLAGS)
$(B)/tests/integration/test_cluster_rewind.o: MODINC := $(INC_TESTS) -Icluster $(CLUSTER_PKG_CFLAGS)

$(B)/tests/%: $(B)/tests/%.o $(ST_LINK)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $< $(ST_LINK) -lcmocka $(LDLIBS) $(CLUSTER_PKG_LIBS)

# Fault injection (tests/common/faultinject.h): test_faults_* binaries get every wrapped call
# redirected to the shim; the daemon tests preload libfaultpreload.so into seamtexd.
FI_WRAP := $(foreach f,malloc calloc realloc strdup aligned_alloc posix_memalign open openat fopen write \
             pwrite fsync fdatasync rename renameat link mkdir,-Wl,--wrap=$(f))
$(B)/tests/unit/test_faults_%: LDFLAGS += $(FI_WRAP)
FAULT_PRELOAD := $(B)/tests/libfaultpreload.so
$(FAULT_PRELOAD): tests/common/faultpreload.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -std=c11 -O2 -g $(WARN) -fPIC -shared -o $@ $< -ldl -lpthread
TEST_BINS += $(FAULT_PRELOAD)

# bench_native's parts: the generated library, the out-of-core comparison and its OpenImageIO
# TextureSystem shim (C++ with extern "C"; bench-only, seamtex itself never links it)
BENCH_NATIVE_OBJ := $(patsubst %,$(B)/tests/bench/%.o,native_lib ooc_compare oiio_texsys)
$(B)/bench/bench_native: $(B)/tests/bench/bench_native.o $(BENCH_NATIVE_OBJ) $(ST_LINK)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $< $(BENCH_NATIVE_OBJ) $(ST_LINK) $(LDLIBS) $(CLUSTER_PKG_LIBS)

$(B)/bench/%: $(B)/tests/bench/%.o $(ST_LINK)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $< $(ST_LINK) $(LDLIBS) $(CLUSTER_PKG_LIBS)

# ---- fuzz targets: clang + libFuzzer + ASan, their own object tree -------------------------
FUZZ_CC   ?= clang
FUZZ_CXX  ?= clang++
FZ        := $(B)/fuzz
FUZZ_SRC  := $(sort $(wildcard tests/fuzz/fuzz_*.c))
FUZZ_BINS := $(patsubst tests/fuzz/%.c,$(FZ)/%,$(FUZZ_SRC))
# UBSan stops at its first report (as SAN=1 does): recovering, it printed and went on, so a
# target passed with undefined behaviour in its log
FUZZ_FLAGS := -g -O1 -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined \
              -fno-omit-frame-pointer
FUZZ_LIB_OBJ := $(STORE_C:%.c=$(FZ)/obj/%.o) $(STORE_CXX:%.cpp=$(FZ)/obj/%.o) \
                $(PROTO_OBJ:$(B)/%.o=$(FZ)/obj/%.o) $(UTIL_OBJ:$(B)/%.o=$(FZ)/obj/%.o)

$(FZ)/obj/util/%.o:     MODINC := $(INC_util)
$(FZ)/obj/protocol/%.o: MODINC := $(INC_protocol)
$(foreach p,$(STORE_PARTS),$(eval $(FZ)/obj/store/$(p)/%.o: MODINC := $(INC_store_$(p))))

$(FZ)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CPPFLAGS) $(MODINC) -std=c11 $(WARN) $(FUZZ_FLAGS) -c $< -o $@

$(FZ)/obj/%.o: %.cpp
	@mkdir -p $(@D)
	$(FUZZ_CXX) $(CPPFLAGS) $(MODINC) -std=c++17 $(WARN) -Wno-unused-parameter $(PKG_CFLAGS) $(FUZZ_FLAGS) -c $< -o $@

$(FZ)/libfuzz.a: $(FUZZ_LIB_OBJ)
	rm -f $@ && ar rcs $@ $^

# a target's own file sees what the tests see; the link goes through clang++ so that UBSan's
# C++ runtime (the vptr checks of the C++ shims: draco.cpp, image_oiio.cpp) is linked in
$(FZ)/obj/tests/fuzz/%.o: tests/fuzz/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(CPPFLAGS) $(INC_TESTS) -std=c11 $(WARN) $(FUZZ_FLAGS) -c $< -o $@

$(FZ)/fuzz_%: $(FZ)/obj/tests/fuzz/fuzz_%.o $(FZ)/libfuzz.a
	$(FUZZ_CXX) -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
		-fno-omit-frame-pointer -o $@ $< \
		$(FZ)/libfuzz.a $(LDLIBS)

# the targets that compile daemon or cluster sources in (fuzz_etcd: cluster/ on json-c, libcurl)
$(FZ)/obj/tests/fuzz/fuzz_etcd.o: INC_TESTS += -Icluster $(CLUSTER_PKG_CFLAGS)
$(FZ)/fuzz_etcd: LDLIBS += $(CLUSTER_PKG_LIBS)

# sanitizer builds (SAN=1, SAN=tsan) leave out the fuzz targets: they have their own tree
ifneq ($(SAN),0)
tests-build: $(TEST_BINS) $(ALL_BINS)
else
tests-build: $(TEST_BINS) $(ALL_BINS) $(FUZZ_BINS)
endif
fuzz-build: $(FUZZ_BINS)
tsan-build: $(filter $(B)/tests/integration/%,$(TEST_BINS)) $(ALL_BINS)
bench-build: $(BENCH_BINS) $(ALL_BINS)

.SECONDARY:

# The CLI's --json output is parsed with json-c (Debian libjson-c-dev) by its tests.
$(B)/tests/unit/test_cli_json_writer $(B)/tests/integration/test_cli: LDLIBS += -ljson-c
# json-c (Debian libjson-c-dev) for the tests that parse seamtexd's JSON log lines
# (tests/common/json_line.c)
JSON_TESTS := $(B)/tests/unit/test_json_log $(B)/tests/integration/test_log_json
$(JSON_TESTS): LDLIBS += $(shell pkg-config --libs json-c 2>/dev/null || echo -ljson-c)
