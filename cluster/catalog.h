/* cluster/catalog.h - the records seamtexd keeps in etcd (docs/cluster.md "Keys").
 *
 * Owns: the key names under the prefix (nodes/, sets/, copies/, ops/, cluster, config), the
 * JSON of the config record, of a node
 * record, of a set record and of an op key, and their parsing (every field checked). Does not
 * own: when records are written (server/cluster_*.c), the HTTP (etcd.h).
 */
#ifndef SCL_CATALOG_H
#define SCL_CATALOG_H

#include <stddef.h>
#include <stdint.h>

#include "stp_cluster.h"

#define SCL_KEY_MAX 640   /* prefix (< 256) + "/copies/" + name (<= 255) + "/" + id (<= 64) */

/* "<prefix>/nodes/", "<prefix>/nodes/<id>", "<prefix>/sets/", "<prefix>/sets/<name>",
 * "<prefix>/copies/<name>/", "<prefix>/copies/<name>/<id>" (id or name "" = the folder). */
void scl_key_node(char *out, const char *prefix, const char *id);
void scl_key_set(char *out, const char *prefix, const char *name);
void scl_key_copies(char *out, const char *prefix, const char *name, const char *id);
/* "<prefix>/copies/" */
void scl_key_all_copies(char *out, const char *prefix);
/* "<prefix>/prev/<name>": the record a pending REPLACE claim replaced, put in the claim's own
 * transaction (so its mod_revision is the claim's): what abandoning that claim records again
 * (server/cluster_repair.c, docs/cluster.md "Repair and rebalance") */
void scl_key_prev(char *out, const char *prefix, const char *name);
/* "<prefix>/ops/<id>": the node's op key (server/cluster_fence.c, docs/cluster.md "Writes in
 * doubt") */
void scl_key_op(char *out, const char *prefix, const char *id);
/* "<prefix>/cluster": the catalogue's identity, 16 hex digits drawn by the node that found the
 * prefix without one (server/cluster_mark.c, docs/cluster.md "Catalogue lost") */
void scl_key_mark(char *out, const char *prefix);
/* "<prefix>/config": the cluster's settings {"replicas":R,"write_quorum":W}, put by the first
 * node that finds none; a node started with others refuses to start (server/cluster_mark.c) */
void scl_key_config(char *out, const char *prefix);
int scl_config_format(char *out, size_t cap, unsigned replicas, unsigned write_quorum);
/* 0, or -1 when the JSON is not a config record (R and W 1..255) */
int scl_config_parse(const char *json, unsigned *replicas, unsigned *write_quorum);

/* The op key's value: {"inc":"<16 hex digits>","seq":N,"op":"<what>","set":"<name>"}; -1 when
 * it does not fit cap. Only the node that wrote it reads it back (compared as bytes). */
int scl_op_format(char *out, size_t cap, uint64_t inc, uint64_t seq, const char *op,
                  const char *name);

/* The node record {"addr":"HOST:PORT","inc":"<16 hex digits>"}: inc is the incarnation of the
 * process that registered (a random id drawn at each start); a record without one parses as 0
 * (unknown). */
int scl_node_format(char *out, size_t cap, const char *addr, uint64_t inc);
int scl_node_parse(const char *json, char *addr, size_t cap, uint64_t *inc);

enum { SCL_SET_PENDING = 0, SCL_SET_OK = 1 };
typedef struct scl_setrec {
    uint32_t crc32c;                  /* of the uploaded file (wire checksum) */
    uint32_t crc32;                   /* of the same file as the data dir's manifest has it */
    uint64_t size;
    char     fmt[16];
    char     options[1024];
    int64_t  version;                 /* 1 at creation, +1 per replace */
    int      state;                   /* SCL_SET_* */
    char     origin[STP_MAX_NODE_ID + 1];
    int      kind;                    /* set kind once "ok", -1 while pending */
    uint64_t inc;                     /* origin's incarnation when it claimed ("inc"; 0 unknown) */
} scl_setrec;
/* JSON of a record; -1 when it does not fit cap. */
int scl_setrec_format(char *out, size_t cap, const scl_setrec *r);
/* 0, or -1 when the JSON is not a set record. */
int scl_setrec_parse(const char *json, scl_setrec *r);

/* A copy record's value: the CRC-32 as 8 hex digits. */
void scl_copy_format(char out[9], uint32_t crc32);
int scl_copy_parse(const char *val, uint32_t *crc32);

#endif
