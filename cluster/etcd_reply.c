/* cluster/etcd_reply.c - decoding etcd's v3 JSON gateway replies and base64 (etcd_reply.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "etcd_reply.h"

/* ---- base64 (RFC 4648, with padding) ---------------------------------------------------------- */

static const char B64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

char *scl_b64_enc(const char *s, size_t n)
{
    char *out = malloc((n + 2) / 3 * 4 + 1), *o = out;
    if (!out)
        return NULL;
    const unsigned char *p = (const unsigned char *)s;
    size_t i = 0;
    for (; i + 2 < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (uint32_t)p[i + 1] << 8 | p[i + 2];
        *o++ = B64[v >> 18]; *o++ = B64[(v >> 12) & 63]; *o++ = B64[(v >> 6) & 63]; *o++ = B64[v & 63];
    }
    if (i < n) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0);
        *o++ = B64[v >> 18];
        *o++ = B64[(v >> 12) & 63];
        *o++ = i + 1 < n ? B64[(v >> 6) & 63] : '=';
        *o++ = '=';
    }
    *o = 0;
    return out;
}

static int b64_val(int c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

char *scl_b64_dec(const char *s, size_t *len)
{
    size_t n = strlen(s);
    if (n % 4)
        return NULL;
    char *out = malloc(n / 4 * 3 + 1);
    if (!out)
        return NULL;
    size_t o = 0;
    for (size_t i = 0; i < n; i += 4) {
        int a = b64_val(s[i]), b = b64_val(s[i + 1]);
        int c = s[i + 2] == '=' ? 0 : b64_val(s[i + 2]);
        int d = s[i + 3] == '=' ? 0 : b64_val(s[i + 3]);
        int pad = (s[i + 2] == '=') + (s[i + 3] == '=');
        if (a < 0 || b < 0 || c < 0 || d < 0 || (pad && i + 4 != n) ||
            (s[i + 2] == '=' && s[i + 3] != '=')) {
            free(out);
            return NULL;
        }
        uint32_t v = (uint32_t)a << 18 | (uint32_t)b << 12 | (uint32_t)c << 6 | (uint32_t)d;
        out[o++] = (char)(v >> 16);
        if (pad < 2) out[o++] = (char)(v >> 8);
        if (pad < 1) out[o++] = (char)v;
    }
    out[o] = 0;
    *len = o;
    return out;
}

/* ---- fields ------------------------------------------------------------------------------------ */

/* o[key] as an int64 into *v: 0 when absent (or null), else a JSON string of decimal digits
 * (etcd's int64) or a JSON integer, not below lo. -1 with a message otherwise. */
static int reply_i64(json_object *o, const char *key, int64_t lo, int64_t *v, char *msg, size_t cap)
{
    json_object *x = NULL;
    *v = 0;
    if (!json_object_object_get_ex(o, key, &x) || !x)
        return 0;
    if (json_object_is_type(x, json_type_int)) {
        *v = json_object_get_int64(x);
    } else if (json_object_is_type(x, json_type_string)) {
        const char *s = json_object_get_string(x), *d = s + (*s == '-');
        char *end;
        errno = 0;
        long long n = *d >= '0' && *d <= '9' ? strtoll(s, &end, 10) : 0;
        if (!(*d >= '0' && *d <= '9') || *end || errno ||
            (size_t)(end - s) != (size_t)json_object_get_string_len(x))
            goto bad;
        *v = n;
    } else {
        goto bad;
    }
    if (*v >= lo)
        return 0;
bad:
    snprintf(msg, cap, "etcd reply: \"%s\" is not %s", key,
             lo >= 0 ? "a non-negative int64" : "an int64");
    *v = 0;
    return -1;
}

/* o[key] as an object into *x: NULL when absent; -1 with a message when not an object */
static int reply_obj(json_object *o, const char *key, json_object **x, char *msg, size_t cap)
{
    *x = NULL;
    if (!json_object_object_get_ex(o, key, x) || !*x)
        return 0;
    if (json_object_is_type(*x, json_type_object))
        return 0;
    snprintf(msg, cap, "etcd reply: \"%s\" is not an object", key);
    *x = NULL;
    return -1;
}

/* the reply itself must be an object */
static int check_reply(json_object *r, const char *what, char *msg, size_t cap)
{
    if (json_object_is_type(r, json_type_object))
        return 0;
    snprintf(msg, cap, "etcd %s: the reply is not a JSON object", what);
    return -1;
}

/* header.revision */
static int reply_revision(json_object *r, int64_t *rev, char *msg, size_t cap)
{
    json_object *hdr;
    *rev = 0;
    if (reply_obj(r, "header", &hdr, msg, cap) != 0)
        return -1;
    return hdr ? reply_i64(hdr, "revision", 0, rev, msg, cap) : 0;
}

int64_t scl_reply_header_revision(json_object *r)
{
    char msg[128];
    int64_t rev = 0;
    if (!json_object_is_type(r, json_type_object) ||
        reply_revision(r, &rev, msg, sizeof msg) != 0)
        return 0;
    return rev;
}

/* kv[field]: absent = "" (proto3); else a base64 string */
static char *reply_b64(json_object *kv, const char *field, int required, size_t *len, char *msg,
                     size_t cap)
{
    json_object *x = NULL;
    char *s = NULL;
    if (!json_object_object_get_ex(kv, field, &x) || !x)
        s = required ? NULL : scl_b64_dec("", len);
    else if (json_object_is_type(x, json_type_string) &&
             strlen(json_object_get_string(x)) == (size_t)json_object_get_string_len(x))
        s = scl_b64_dec(json_object_get_string(x), len);
    if (!s)
        snprintf(msg, cap, "etcd range: kvs[].%s is %s", field, x ? "not base64" : "missing");
    return s;
}

/* ---- replies ------------------------------------------------------------------------------------ */

void scl_kvs_free(scl_kvs *k)
{
    if (!k)
        return;
    for (size_t i = 0; i < k->n; i++) {
        free(k->v[i].key);
        free(k->v[i].val);
    }
    free(k->v);
    memset(k, 0, sizeof *k);
}

int scl_reply_range(json_object *r, scl_kvs *out, char *msg, size_t cap)
{
    json_object *kvs = NULL;
    memset(out, 0, sizeof *out);
    if (check_reply(r, "range", msg, cap) != 0 || reply_revision(r, &out->revision, msg, cap) != 0)
        return SCL_EBADREPLY;
    if (!json_object_object_get_ex(r, "kvs", &kvs) || !kvs)
        return SCL_OK;
    if (!json_object_is_type(kvs, json_type_array)) {
        snprintf(msg, cap, "etcd range: kvs is not an array");
        return SCL_EBADREPLY;
    }
    size_t n = json_object_array_length(kvs);
    out->v = calloc(n ? n : 1, sizeof *out->v);
    if (!out->v) {
        snprintf(msg, cap, "etcd range: out of memory for %zu keys", n);
        return SCL_ENOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        json_object *kv = json_object_array_get_idx(kvs, i);
        scl_kv *d = &out->v[out->n];
        if (!json_object_is_type(kv, json_type_object)) {
            snprintf(msg, cap, "etcd range: kvs[%zu] is not an object", i);
            goto bad;
        }
        d->key = reply_b64(kv, "key", 1, &d->key_len, msg, cap);
        d->val = d->key ? reply_b64(kv, "value", 0, &d->val_len, msg, cap) : NULL;
        if (!d->key || !d->val || !d->key_len) {
            if (d->key && d->val)
                snprintf(msg, cap, "etcd range: kvs[%zu].key is empty", i);
            free(d->key);
            free(d->val);
            d->key = d->val = NULL;
            goto bad;
        }
        out->n++;
        if (reply_i64(kv, "create_revision", 0, &d->create_rev, msg, cap) ||
            reply_i64(kv, "mod_revision", 0, &d->mod_rev, msg, cap) ||
            reply_i64(kv, "version", 0, &d->version, msg, cap) ||
            reply_i64(kv, "lease", 0, &d->lease, msg, cap))
            goto bad;
    }
    return SCL_OK;
bad:
    scl_kvs_free(out);
    return SCL_EBADREPLY;
}

int scl_reply_grant(json_object *r, int64_t *lease, char *msg, size_t cap)
{
    *lease = 0;
    if (check_reply(r, "lease grant", msg, cap) != 0 || reply_i64(r, "ID", 0, lease, msg, cap) != 0)
        return SCL_EBADREPLY;
    if (*lease == 0) {
        snprintf(msg, cap, "etcd lease grant: no ID in the reply");
        return SCL_EBADREPLY;
    }
    return SCL_OK;
}

int scl_reply_keepalive(json_object *r, int64_t *ttl, char *msg, size_t cap)
{
    /* the gateway streams: one request message in, one {"result": {...}} out */
    json_object *res;
    *ttl = 0;
    if (check_reply(r, "keepalive", msg, cap) != 0 || reply_obj(r, "result", &res, msg, cap) != 0)
        return SCL_EBADREPLY;
    if (!res) {
        snprintf(msg, cap, "etcd keepalive: no result in the reply");
        return SCL_EBADREPLY;
    }
    if (reply_i64(res, "TTL", INT64_MIN, ttl, msg, cap) != 0)
        return SCL_EBADREPLY;
    if (*ttl < 0)
        *ttl = 0;      /* an expired lease (etcd says 0; a negative TTL means the same) */
    return SCL_OK;
}

int scl_reply_txn(json_object *r, int *succeeded, int64_t *revision, char *msg, size_t cap)
{
    json_object *v = NULL;
    int64_t rev;
    *succeeded = 0;
    if (check_reply(r, "txn", msg, cap) != 0 || reply_revision(r, &rev, msg, cap) != 0)
        return SCL_EBADREPLY;
    if (json_object_object_get_ex(r, "succeeded", &v) && v) {
        if (!json_object_is_type(v, json_type_boolean)) {
            snprintf(msg, cap, "etcd txn: \"succeeded\" is not a boolean");
            return SCL_EBADREPLY;
        }
        *succeeded = json_object_get_boolean(v);
    }
    if (revision)
        *revision = rev;
    return SCL_OK;
}
