/* cluster/etcd_reply.h - the decoders of etcd's v3 JSON gateway replies (etcd.c's half that
 * reads outside bytes), apart from the HTTP so that they can be tested and fuzzed alone
 * (tests/fuzz/fuzz_etcd.c).
 *
 * Owns: base64 (RFC 4648 with padding) of keys and values, etcd's int64-as-JSON-string
 * fields, the shapes of the range, lease grant, lease keepalive and txn replies. Does not own:
 * the HTTP (etcd.c), what keys mean (catalog.h).
 *
 * Rules (etcd 3.4's gateway writes proto3 JSON): a reply is a JSON object; an absent field is
 * 0 / false / empty (proto3 leaves defaults out); an int64 is a JSON string of decimal digits
 * (a JSON integer is taken too); a revision, version or lease id is never negative. Anything
 * else is SCL_EBADREPLY with a message naming the field: never a silent 0.
 * Errors: SCL_OK, SCL_EBADREPLY or SCL_ENOMEM (etcd.h), a message in msg (cap bytes).
 * Ownership: the json_object stays the caller's; an scl_kvs filled is the caller's
 * (scl_kvs_free), and is left empty on an error.
 */
#ifndef SCL_ETCD_REPLY_H
#define SCL_ETCD_REPLY_H

#include <json.h>
#include <stddef.h>
#include <stdint.h>

#include "etcd.h"

/* base64 of n bytes (malloc'd, NUL-terminated), or NULL when out of memory */
char *scl_b64_enc(const char *s, size_t n);
/* the bytes of a base64 text (malloc'd, NUL-terminated, *len without the NUL), or NULL when
 * s is not base64 (or out of memory) */
char *scl_b64_dec(const char *s, size_t *len);

/* /v3/kv/range: header.revision and kvs[] (key, value, create_revision, mod_revision,
 * version, lease; the key is required) */
int scl_reply_range(json_object *r, scl_kvs *out, char *msg, size_t cap);
/* /v3/lease/grant: ID, required and positive */
int scl_reply_grant(json_object *r, int64_t *lease, char *msg, size_t cap);
/* /v3/lease/keepalive: result.TTL (0 when etcd no longer knows the lease) */
int scl_reply_keepalive(json_object *r, int64_t *ttl, char *msg, size_t cap);
/* header.revision of any reply; 0 when absent or not a non-negative int64 (etcd.c's revision
 * watch: never an error of its own, the call's decoder judges the reply) */
int64_t scl_reply_header_revision(json_object *r);
/* /v3/kv/txn: succeeded, header.revision */
int scl_reply_txn(json_object *r, int *succeeded, int64_t *revision, char *msg, size_t cap);

#endif
