/* cluster/catalog.c - key names and JSON records of the cluster's etcd keys (catalog.h). */
#include <json.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "catalog.h"

void scl_key_node(char *out, const char *prefix, const char *id)
{
    snprintf(out, SCL_KEY_MAX, "%s/nodes/%s", prefix, id);
}

void scl_key_set(char *out, const char *prefix, const char *name)
{
    snprintf(out, SCL_KEY_MAX, "%s/sets/%s", prefix, name);
}

void scl_key_copies(char *out, const char *prefix, const char *name, const char *id)
{
    snprintf(out, SCL_KEY_MAX, "%s/copies/%s/%s", prefix, name, id);
}

void scl_key_all_copies(char *out, const char *prefix)
{
    snprintf(out, SCL_KEY_MAX, "%s/copies/", prefix);
}

void scl_key_prev(char *out, const char *prefix, const char *name)
{
    snprintf(out, SCL_KEY_MAX, "%s/prev/%s", prefix, name);
}

void scl_key_op(char *out, const char *prefix, const char *id)
{
    snprintf(out, SCL_KEY_MAX, "%s/ops/%s", prefix, id);
}

void scl_key_mark(char *out, const char *prefix)
{
    snprintf(out, SCL_KEY_MAX, "%s/cluster", prefix);
}

void scl_key_config(char *out, const char *prefix)
{
    snprintf(out, SCL_KEY_MAX, "%s/config", prefix);
}

int scl_config_format(char *out, size_t cap, unsigned replicas, unsigned write_quorum)
{
    int n = snprintf(out, cap, "{\"replicas\":%u,\"write_quorum\":%u}", replicas, write_quorum);
    return n > 0 && (size_t)n < cap ? 0 : -1;
}

/* the incarnation as 16 hex digits (a JSON number cannot hold 64 bits exactly) */
static void add_inc(json_object *o, uint64_t inc)
{
    char hex[17];
    snprintf(hex, sizeof hex, "%016llx", (unsigned long long)inc);
    json_object_object_add(o, "inc", json_object_new_string(hex));
}

/* "inc" of o into *inc: 0 when absent (a record of an older node), -1 when malformed */
static int get_inc(json_object *o, uint64_t *inc)
{
    json_object *x;
    *inc = 0;
    if (!json_object_object_get_ex(o, "inc", &x))
        return 0;
    if (!json_object_is_type(x, json_type_string))
        return -1;
    const char *s = json_object_get_string(x);
    if (strlen(s) != 16 || strspn(s, "0123456789abcdef") != 16)
        return -1;
    *inc = strtoull(s, NULL, 16);
    return 0;
}

int scl_op_format(char *out, size_t cap, uint64_t inc, uint64_t seq, const char *op,
                  const char *name)
{
    json_object *o = json_object_new_object();
    add_inc(o, inc);
    json_object_object_add(o, "seq", json_object_new_int64((int64_t)seq));
    json_object_object_add(o, "op", json_object_new_string(op));
    json_object_object_add(o, "set", json_object_new_string(name));
    int n = snprintf(out, cap, "%s", json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN));
    json_object_put(o);
    return n < 0 || (size_t)n >= cap ? -1 : 0;
}

int scl_node_format(char *out, size_t cap, const char *addr, uint64_t inc)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "addr", json_object_new_string(addr));
    add_inc(o, inc);
    int n = snprintf(out, cap, "%s", json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN));
    json_object_put(o);
    return n < 0 || (size_t)n >= cap ? -1 : 0;
}

int scl_node_parse(const char *json, char *addr, size_t cap, uint64_t *inc)
{
    json_object *o = json_tokener_parse(json), *a = NULL;
    int rc = -1;
    if (o && json_object_object_get_ex(o, "addr", &a) && json_object_is_type(a, json_type_string) &&
        get_inc(o, inc) == 0) {
        const char *s = json_object_get_string(a);
        size_t n = strlen(s);
        if (n > 0 && n < cap && n <= STP_MAX_NODE_ADDR && strchr(s, ':') &&
            n == (size_t)json_object_get_string_len(a)) {
            memcpy(addr, s, n + 1);
            rc = 0;
        }
    }
    json_object_put(o);
    return rc;
}

int scl_setrec_format(char *out, size_t cap, const scl_setrec *r)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "crc32c", json_object_new_int64(r->crc32c));
    json_object_object_add(o, "crc32", json_object_new_int64(r->crc32));
    json_object_object_add(o, "size", json_object_new_int64((int64_t)r->size));
    json_object_object_add(o, "fmt", json_object_new_string(r->fmt));
    json_object_object_add(o, "options", json_object_new_string(r->options));
    json_object_object_add(o, "version", json_object_new_int64(r->version));
    json_object_object_add(o, "state", json_object_new_string(r->state == SCL_SET_OK ? "ok" : "pending"));
    json_object_object_add(o, "origin", json_object_new_string(r->origin));
    add_inc(o, r->inc);
    json_object_object_add(o, "kind", json_object_new_int(r->kind));
    int n = snprintf(out, cap, "%s", json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN));
    json_object_put(o);
    return n < 0 || (size_t)n >= cap ? -1 : 0;
}

static int get_i64(json_object *o, const char *k, int64_t lo, int64_t hi, int64_t *v)
{
    json_object *x;
    if (!json_object_object_get_ex(o, k, &x) || !json_object_is_type(x, json_type_int))
        return -1;
    *v = json_object_get_int64(x);
    return *v < lo || *v > hi ? -1 : 0;
}

static int get_str(json_object *o, const char *k, char *out, size_t cap)
{
    json_object *x;
    if (!json_object_object_get_ex(o, k, &x) || !json_object_is_type(x, json_type_string))
        return -1;
    const char *s = json_object_get_string(x);
    size_t n = strlen(s);
    if (n >= cap || n != (size_t)json_object_get_string_len(x))
        return -1;     /* too long, or a "\u0000" inside */
    memcpy(out, s, n + 1);
    return 0;
}

int scl_setrec_parse(const char *json, scl_setrec *r)
{
    memset(r, 0, sizeof *r);
    json_object *o = json_tokener_parse(json);
    if (!o)
        return -1;
    int64_t c32c, c32, size, ver, kind;
    char state[16];
    int bad = get_i64(o, "crc32c", 0, UINT32_MAX, &c32c) || get_i64(o, "crc32", 0, UINT32_MAX, &c32) ||
              get_i64(o, "size", 0, INT64_MAX, &size) || get_i64(o, "version", 1, INT64_MAX, &ver) ||
              get_i64(o, "kind", -1, 255, &kind) || get_str(o, "fmt", r->fmt, sizeof r->fmt) ||
              get_str(o, "options", r->options, sizeof r->options) ||
              get_str(o, "origin", r->origin, sizeof r->origin) ||
              get_str(o, "state", state, sizeof state) || get_inc(o, &r->inc);
    json_object_put(o);
    if (bad)
        return -1;
    if (!strcmp(state, "ok"))
        r->state = SCL_SET_OK;
    else if (!strcmp(state, "pending"))
        r->state = SCL_SET_PENDING;
    else
        return -1;
    r->crc32c = (uint32_t)c32c;
    r->crc32 = (uint32_t)c32;
    r->size = (uint64_t)size;
    r->version = ver;
    r->kind = (int)kind;
    return 0;
}

void scl_copy_format(char out[9], uint32_t crc32)
{
    snprintf(out, 9, "%08x", crc32);
}

int scl_copy_parse(const char *val, uint32_t *crc32)
{
    /* exactly 8 hex digits: strtoul alone would take " -1", "+1234567" or "0x123456" */
    if (strlen(val) != 8 || strspn(val, "0123456789abcdefABCDEF") != 8)
        return -1;
    *crc32 = (uint32_t)strtoul(val, NULL, 16);
    return 0;
}

int scl_config_parse(const char *json, unsigned *replicas, unsigned *write_quorum)
{
    json_object *o = json_tokener_parse(json);
    int64_t r = 0, w = 0;
    int rc = o && json_object_is_type(o, json_type_object) &&
             get_i64(o, "replicas", 1, 255, &r) == 0 && get_i64(o, "write_quorum", 1, 255, &w) == 0
             ? 0 : -1;
    json_object_put(o);
    if (rc == 0) {
        *replicas = (unsigned)r;
        *write_quorum = (unsigned)w;
    }
    return rc;
}
