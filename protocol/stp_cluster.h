/* protocol/stp_cluster.h - what server and client must agree on in a cluster: placement by
 * rendezvous (HRW) hashing and the CLUSTER reply body (PROTOCOL.md 4.11, docs/cluster.md).
 *
 * Owns: the HRW score and ranking (one implementation, so every node and every client
 * computes the same owners from the same membership), the CLUSTER reply layout and its
 * encoder / decoder. Does not own: where the membership comes from (etcd, server/), routing
 * and failover (client/libcluster.c).
 *
 * libc only; reentrant; no allocation (the decoder points into the body).
 */
#ifndef STP_CLUSTER_H
#define STP_CLUSTER_H

#include <stddef.h>
#include <stdint.h>

#include "proto.h"

#define STP_MAX_NODE_ID   64    /* node ids: 1..64 bytes of [A-Za-z0-9._-] */
#define STP_MAX_NODE_ADDR 255   /* "host:port" */
#define STP_MAX_NODES     4096  /* members in one CLUSTER reply */

/* 0 when the len bytes at id are a valid node id, else -1. */
int stp_node_id_check(const char *id, size_t len);

/* Splits "host:port" or "[v6]:port" into host (cap bytes) and port 1..65535; 0 or -1. */
int stp_split_addr(const char *addr, char *host, size_t cap, unsigned *port);

/* score(node, name): FNV-1a 64 over the node id, a 0 byte and the set name, then the
 * splitmix64 finaliser (docs/cluster.md gives the constants). */
uint64_t stp_hrw_score(const char *node, size_t node_len, const char *name, size_t name_len);

/* Ranks n nodes (ids[i], NUL-terminated) for name: writes the indices of the first k of the
 * ranking (highest score first, equal scores by id bytewise ascending) into order[]; returns
 * min(k, n). The owners of name with R replicas are the first min(R, n). */
size_t stp_hrw_rank(const char *const *ids, size_t n, const char *name, size_t *order, size_t k);

/* CLUSTER reply (PROTOCOL.md 4.11). */
typedef struct stp_cluster_node {
    const char *id;      /* points into the body when decoded: NOT NUL-terminated, use *_len */
    uint16_t    id_len;
    const char *addr;
    uint16_t    addr_len;
} stp_cluster_node;

typedef struct stp_cluster_reply {
    uint64_t epoch;        /* etcd revision of the membership seen (changes when it does) */
    uint8_t  replicas;     /* R */
    uint8_t  write_quorum; /* W */
    uint8_t  flags;        /* STP_CLF_* */
    char     self_id[STP_MAX_NODE_ID + 1];
    uint32_t count;
    const stp_cluster_node *nodes;   /* encoder: count entries */
    const uint8_t *raw;    /* decoder: the entries' bytes (stp_cluster_next walks them) */
    size_t   raw_len;
} stp_cluster_reply;

enum { STP_CLF_ETCD_OK = 1 };  /* the node reached etcd on its last try */

int stp_enc_cluster_reply(stp_buf *b, uint32_t reqid, const stp_cluster_reply *r);
int stp_dec_cluster_reply(const uint8_t *body, size_t len, stp_cluster_reply *r,
                          const char **why);
/* Walks the entries of a decoded reply: 1 and *e filled, 0 at the end. */
int stp_cluster_next(const stp_cluster_reply *r, size_t *pos, stp_cluster_node *e);

#endif
