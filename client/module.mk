# client/module.mk - libseamtex (the client library), the CLI `seamtex`, the load tester
# `seamtex-bench`. Included by the top Makefile.

# libseamtex and the CLI see client/, protocol/ and util/ headers only: an #include of a
# store/ or server/ header fails to compile. seamtex-bench (bench*.c) also sees the store: its
# in-process baseline samples with it and shares its query generator, on purpose.
$(B)/client/%.o: MODINC := -Iclient -Iprotocol $(INC_util)
$(B)/client/bench%.o: MODINC := -Iclient -Iprotocol $(INC_STORE)

# ---- libseamtex (owner: client library) ----
# libseamtex.a bundles the protocol and util objects so that an installed client needs only
# -lseamtex.
CLIENT_LIB_SRC := $(sort $(wildcard client/lib*.c))
LIB_CLIENT     := $(B)/libseamtex.a
$(LIB_CLIENT): $(CLIENT_LIB_SRC:%.c=$(B)/%.o) $(PROTO_OBJ) $(UTIL_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^
ALL_BINS     += $(LIB_CLIENT)
INSTALL_LIBS += $(LIB_CLIENT)
INSTALL_HDRS += client/seamtex.h client/seamtex_cluster.h client/seamtex_etcd.h

# ---- seamtex CLI and seamtex-bench (owner: CLI / load tester) ----
# Neither program is a library: their objects stay out of libseamtex.a (which takes lib*.c).
# The CLI is a client like any other: it links libseamtex (which holds the protocol objects),
# libseamtex_etcd with libcurl and json-c (--cluster etcd://...) and libc/libm, never the
# store; --as-needed keeps the image libraries that LDLIBS names out of seamtex-bench when its
# in-process baseline does not need them.
CLI_SRC   := $(sort $(wildcard client/seamtex_cli.c client/cli_*.c))
BENCH_SRC_CLIENT := $(sort $(wildcard client/bench*.c)) client/hist.c

$(B)/seamtex: $(CLI_SRC:%.c=$(B)/%.o) $(LIB_ETCD) $(LIB_CLIENT)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $(filter %.o,$^) $(LIB_ETCD) $(LIB_CLIENT) -lm -lpthread $(CLUSTER_PKG_LIBS)

$(B)/seamtex-bench: $(BENCH_SRC_CLIENT:%.c=$(B)/%.o) $(LIB_ETCD) $(LIB_CLIENT) $(LIB_PROTO) $(LIB_STORE)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -Wl,--as-needed -o $@ $(filter %.o,$^) $(LIB_ETCD) $(LIB_CLIENT) $(LIB_PROTO) $(LIB_STORE) $(LDLIBS) $(CLUSTER_PKG_LIBS)

ALL_BINS     += $(B)/seamtex-bench
INSTALL_BINS += $(B)/seamtex-bench
# the CLI needs libseamtex's sources
ifneq ($(CLIENT_LIB_SRC),)
ALL_BINS     += $(B)/seamtex
INSTALL_BINS += $(B)/seamtex
endif
