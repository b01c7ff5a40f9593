# server/module.mk - the daemon seamtexd. Included by the top Makefile.
#
# $(B)/seamtexd is linked from every server/*.c with libseamtex_proto.a, every store part's
# archive, libseamtex_util.a and the common LDLIBS.

SERVER_SRC := $(sort $(wildcard server/*.c))
SERVER_OBJ := $(SERVER_SRC:%.c=$(B)/%.o)

# The daemon sees every store part, protocol/ and util/ (it is the top of the graph).
# cluster/ too (cluster/module.mk), and with it libseamtex (node-to-node copies) and libcurl,
# json-c.
$(B)/server/%.o: MODINC := -Iserver -Iprotocol $(INC_STORE) -Icluster
SERVER_LINK := $(LIB_CLUSTER) $(LIB_CLIENT) $(LIB_PROTO) $(LIB_STORE)

$(B)/seamtexd: $(SERVER_OBJ) $(SERVER_LINK)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $(SERVER_OBJ) $(SERVER_LINK) $(LDLIBS) $(CLUSTER_PKG_LIBS)

# The daemon's objects without main(), for tests that check its tables (tests/unit/
# test_protodoc.c: PROTOCOL.md's caps table against sts_handler_find).
LIB_SERVER := $(B)/libseamtexd.a
$(LIB_SERVER): $(filter-out $(B)/server/main.o,$(SERVER_OBJ))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

ALL_BINS     += $(B)/seamtexd
INSTALL_BINS += $(B)/seamtexd
