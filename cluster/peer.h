/* cluster/peer.h - node-to-node requests over the seamtex wire protocol (libseamtex).
 *
 * Owns: pushing a stored source file to another node as a REPLICA upload (its CRC-32C is
 * computed from the file and checked by the receiver at commit: end to end; with STAGE the
 * receiver keeps it staged), telling a node to publish its staged copy (REPLICA_PUBLISH),
 * forwarding a DELETE, asking whether a node answers (PING) and which node answers at an
 * address (CLUSTER). Does not own: choosing the
 * target (cluster_node.c), the protocol (protocol/).
 * Blocking; each call opens and closes its own connection. Returns 0 or an STC_E* code, with
 * a message in msg (scl_peer_publish: also SCL_PEER_NOT_FOUND).
 */
#ifndef SCL_PEER_H
#define SCL_PEER_H

#include <stddef.h>
#include <stdint.h>

/* stage: the copy of a write not recorded yet (REPLICA + STAGE: the receiver stages it until
 * scl_peer_publish or its own repair pass publishes it) */
int scl_peer_push(const char *addr, const char *token, const char *path, const char *name,
                  const char *hint, const char *options, int stage, int timeout_ms,
                  uint32_t *crc32c, char *msg, size_t cap);
/* REPLICA_PUBLISH: the receiver publishes its staged copy of name whose source has CRC-32
 * crc32 (the write has been recorded). SCL_PEER_NOT_FOUND (msg filled) when the receiver has
 * no staged copy of those contents and answers NOT_FOUND: after a REPLACE, a holder of the
 * old contents that hid its copy (PROTOCOL.md 4.11). */
enum { SCL_PEER_NOT_FOUND = 1 };
int scl_peer_publish(const char *addr, const char *token, const char *name, uint32_t crc32,
                     int timeout_ms, char *msg, size_t cap);
/* 0 when a server answers PING at addr within timeout_ms (connect and reply), else the
 * STC_E* code (seamtexd: is the process that registered a node id still there?) */
int scl_peer_ping(const char *addr, int timeout_ms);
/* CLUSTER at addr: 0 and the answering node's id in id (idcap bytes), else the STC_E* code or
 * the reply's status, with msg set (seamtexd: does its --advertise address reach it?) */
int scl_peer_self_id(const char *addr, int timeout_ms, char *id, size_t idcap, char *msg,
                     size_t cap);
int scl_peer_delete(const char *addr, const char *token, const char *name, int timeout_ms,
                    char *msg, size_t cap);

#endif
