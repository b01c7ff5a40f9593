# server/module.mk - the daemon seamtexd. Included by the top Makefile.
#
# $(B)/seamtexd is linked from every server/*.c with libseamtex_proto.a, libseamtex_store.a
# and the common LDLIBS.

SERVER_SRC := $(sort $(wildcard server/*.c))
SERVER_OBJ := $(SERVER_SRC:%.c=$(B)/%.o)

$(SERVER_OBJ): CPPFLAGS += -Iserver

$(B)/seamtexd: $(SERVER_OBJ) $(LIB_PROTO) $(LIB_STORE)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $(SERVER_OBJ) $(LIB_PROTO) $(LIB_STORE) $(LDLIBS)

ALL_BINS     += $(B)/seamtexd
INSTALL_BINS += $(B)/seamtexd
