# cluster/module.mk - libseamtex_cluster.a: the etcd gateway client, the cluster's etcd
# records and node-to-node copies. Included by the top Makefile before server/module.mk.
#
# Dependency rule (ARCHITECTURE.md): cluster/ uses protocol/ (placement, names), libseamtex
# through its installed header only (node-to-node copies speak the wire protocol as any client
# does: the header is copied to $(B)/include/ and that is the only client/ path cluster/ sees),
# libcurl and json-c; never server/ or store/. Only server/ uses cluster/.
CLUSTER_PKG_CFLAGS := $(shell pkg-config --cflags libcurl json-c 2>/dev/null)
CLUSTER_PKG_LIBS   := $(shell pkg-config --libs libcurl json-c 2>/dev/null)
CLUSTER_OBJ := $(patsubst %.c,$(B)/%.o,$(sort $(wildcard cluster/*.c)))
INC_cluster := -Icluster -Iprotocol -I$(B)/include
$(B)/cluster/%.o: MODINC := $(INC_cluster) $(CLUSTER_PKG_CFLAGS)
$(B)/include/%.h: client/%.h
	@mkdir -p $(@D)
	cp $< $@
CLUSTER_INC_HDRS := $(addprefix $(B)/include/,seamtex.h seamtex_cluster.h seamtex_etcd.h)
$(CLUSTER_OBJ): $(CLUSTER_INC_HDRS)
LIB_CLUSTER := $(B)/libseamtex_cluster.a
$(LIB_CLUSTER): $(CLUSTER_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# libseamtex_etcd.a (client/seamtex_etcd.h): stc_cluster_open_etcd for clients (the CLI,
# seamtex-bench, programs that open a cluster from its etcd URL), so that libseamtex.a itself
# never needs libcurl or json-c. Link: -lseamtex_etcd -lseamtex + libcurl, json-c.
LIB_ETCD := $(B)/libseamtex_etcd.a
$(LIB_ETCD): $(addprefix $(B)/cluster/,etcd.o etcd_reply.o catalog.o etcd_open.o)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^
ALL_BINS     += $(LIB_ETCD)
INSTALL_LIBS += $(LIB_ETCD)
