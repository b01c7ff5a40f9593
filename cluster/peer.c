/* cluster/peer.c - node-to-node copies, publishes and deletes (peer.h), built on libseamtex. */
#include <stdio.h>
#include <string.h>

#include "peer.h"
#include "proto.h"
#include "seamtex.h"
#include "stp_cluster.h"

static stc_conn *dial(const char *addr, const char *token, int timeout_ms, int *rc, char *msg,
                      size_t cap)
{
    char host[256];
    unsigned port;
    if (stp_split_addr(addr, host, sizeof host, &port) != 0) {
        snprintf(msg, cap, "bad node address '%.200s'", addr);
        *rc = STC_EINVAL;
        return NULL;
    }
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.connect_timeout_ms = timeout_ms;
    o.request_timeout_ms = timeout_ms;
    o.token = token && *token ? token : NULL;
    o.client_name = "seamtexd-peer";
    char em[256] = "";
    stc_conn *c = stc_connect_opts(host, port, &o, rc, em, sizeof em);
    if (!c)
        snprintf(msg, cap, "connect %s: %s", addr, em);
    return c;
}

int scl_peer_push(const char *addr, const char *token, const char *path, const char *name,
                  const char *hint, const char *options, int stage, int timeout_ms,
                  uint32_t *crc32c, char *msg, size_t cap)
{
    int rc = 0;
    stc_conn *c = dial(addr, token, timeout_ms, &rc, msg, cap);
    if (!c)
        return rc;
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = hint && *hint ? hint : NULL;
    uo.options = options && *options ? options : NULL;
    uo.flags = STC_UPLOAD_REPLACE | STC_UPLOAD_REPLICA | (stage ? STC_UPLOAD_STAGE : 0);
    stc_upload_result res;
    rc = stc_upload_file(c, path, name, &uo, &res);
    if (rc)
        snprintf(msg, cap, "push of '%s' to %s: %s", name, addr, stc_errmsg(c));
    else if (crc32c)
        *crc32c = res.crc32c;
    stc_close(c);
    return rc;
}

int scl_peer_ping(const char *addr, int timeout_ms)
{
    int rc = 0;
    char msg[320];
    stc_conn *c = dial(addr, NULL, timeout_ms, &rc, msg, sizeof msg);
    if (!c)
        return rc ? rc : STC_ECONNECT;
    rc = stc_ping(c);
    stc_close(c);
    return rc;
}

int scl_peer_self_id(const char *addr, int timeout_ms, char *id, size_t idcap, char *msg,
                     size_t cap)
{
    int rc = 0;
    stc_conn *c = dial(addr, NULL, timeout_ms, &rc, msg, cap);
    if (!c)
        return rc ? rc : STC_ECONNECT;
    uint32_t reqid;
    stc_reply r;
    rc = stc_append_raw(c, STP_OP_CLUSTER, NULL, 0, &reqid);
    if (rc == 0)
        rc = stc_flush(c);
    if (rc == 0)
        rc = stc_get_reply(c, -1, &r);
    if (rc) {
        snprintf(msg, cap, "CLUSTER on %s: %s", addr, stc_errmsg(c));
    } else if (r.status) {
        snprintf(msg, cap, "CLUSTER on %s: %s", addr, r.errmsg);
        rc = r.status;
    } else {
        stp_cluster_reply cr;
        const char *why = NULL;
        if (stp_dec_cluster_reply(r.body, r.body_len, &cr, &why) != 0) {
            snprintf(msg, cap, "CLUSTER on %s: %s", addr, why ? why : "bad reply");
            rc = STC_EPROTO;
        } else {
            snprintf(id, idcap, "%s", cr.self_id);
        }
    }
    stc_close(c);
    return rc;
}

int scl_peer_delete(const char *addr, const char *token, const char *name, int timeout_ms,
                    char *msg, size_t cap)
{
    int rc = 0;
    stc_conn *c = dial(addr, token, timeout_ms, &rc, msg, cap);
    if (!c)
        return rc;
    rc = stc_delete(c, name);
    if (rc && rc != STC_ENOTFOUND)
        snprintf(msg, cap, "delete of '%s' on %s: %s", name, addr, stc_errmsg(c));
    stc_close(c);
    return rc == STC_ENOTFOUND ? 0 : rc;
}

int scl_peer_publish(const char *addr, const char *token, const char *name, uint32_t crc32,
                     int timeout_ms, char *msg, size_t cap)
{
    int rc = 0;
    stc_conn *c = dial(addr, token, timeout_ms, &rc, msg, cap);
    if (!c)
        return rc;
    stp_buf b;
    stp_buf_init(&b);
    uint32_t id = 0;
    stc_reply r;
    memset(&r, 0, sizeof r);
    if (stp_put_replica_publish(&b, name, crc32) != 0)
        rc = STC_ENOMEM;
    if (!rc)
        rc = stc_append_raw(c, STP_OP_REPLICA_PUBLISH, stp_buf_head(&b), stp_buf_avail(&b), &id);
    if (!rc)
        rc = stc_flush(c);
    if (!rc)
        rc = stc_get_reply(c, -1, &r);
    if (!rc && r.status)
        rc = r.status;
    if (rc)
        snprintf(msg, cap, "publish of '%s' on %s: %s", name, addr,
                 r.status && rc == r.status ? r.errmsg : stc_errmsg(c));
    stp_buf_free(&b);
    stc_close(c);
    return rc == STC_ENOTFOUND ? SCL_PEER_NOT_FOUND : rc;
}
