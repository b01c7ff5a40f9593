# client/module.mk - libseamtex (the client library), the CLI `seamtex`, the load tester
# `seamtex-bench`. Included by the top Makefile.

# client/ sees protocol/ and util/ only; seamtex-bench's in-process baseline (bench_inproc.c)
# also sees the store's sample and core parts, on purpose.
$(B)/client/%.o: MODINC := -Iclient -Iprotocol $(INC_util) -Istore/core -Istore/sample  # TEMP: until protocol/ names modes
$(B)/client/bench_inproc.o: MODINC := -Iclient -Iprotocol $(INC_util) $(INC_STORE)

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
INSTALL_HDRS += client/seamtex.h

# ---- seamtex CLI and seamtex-bench (owner: CLI / load tester) ----
# Neither program is a library: their objects stay out of libseamtex.a (which takes lib*.c).
# --as-needed keeps the image libraries that LDLIBS names out of binaries that do not use them.
CLI_SRC   := $(sort $(wildcard client/seamtex_cli.c client/cli_*.c))
BENCH_SRC_CLIENT := $(sort $(wildcard client/bench*.c)) client/hist.c

$(B)/seamtex: $(CLI_SRC:%.c=$(B)/%.o) $(LIB_CLIENT) $(LIB_PROTO) $(LIB_STORE)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -Wl,--as-needed -o $@ $(filter %.o,$^) $(LIB_CLIENT) $(LIB_PROTO) \
		$(LIB_STORE) $(LDLIBS)

$(B)/seamtex-bench: $(BENCH_SRC_CLIENT:%.c=$(B)/%.o) $(LIB_PROTO) $(LIB_STORE)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -Wl,--as-needed -o $@ $(filter %.o,$^) $(LIB_PROTO) $(LIB_STORE) $(LDLIBS)

ALL_BINS     += $(B)/seamtex-bench
INSTALL_BINS += $(B)/seamtex-bench
# the CLI needs libseamtex's sources
ifneq ($(CLIENT_LIB_SRC),)
ALL_BINS     += $(B)/seamtex
INSTALL_BINS += $(B)/seamtex
endif
