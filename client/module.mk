# client/module.mk - libseamtex (the client library), the CLI `seamtex`, the load tester
# `seamtex-bench`. Included by the top Makefile.

# ---- libseamtex (owner: client library) ----
CLIENT_LIB_SRC := $(sort $(wildcard client/lib*.c))
LIB_CLIENT     := $(B)/libseamtex.a
$(LIB_CLIENT): $(CLIENT_LIB_SRC:%.c=$(B)/%.o)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^
ALL_BINS     += $(LIB_CLIENT)
INSTALL_LIBS += $(LIB_CLIENT)
INSTALL_HDRS += client/seamtex.h

# ---- seamtex CLI and seamtex-bench (owner: CLI / load tester) ----
