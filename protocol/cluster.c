/* protocol/cluster.c - HRW placement and the CLUSTER reply body (stp_cluster.h).
 *
 * Owns: the score function and ranking, the CLUSTER reply's bytes. Does not own: the
 * membership itself or what a node does with the ranking.
 */
#include "stp_cluster.h"

int stp_node_id_check(const char *id, size_t len)
{
    if (len == 0 || len > STP_MAX_NODE_ID)
        return -1;
    for (size_t i = 0; i < len; i++) {
        unsigned char ch = (unsigned char)id[i];
        int ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
                 ch == '.' || ch == '_' || ch == '-';
        if (!ok)
            return -1;
    }
    return 0;
}

int stp_split_addr(const char *addr, char *host, size_t cap, unsigned *port)
{
    const char *colon = strrchr(addr, ':');
    if (!colon || colon == addr)
        return -1;
    const char *h = addr;
    size_t hl = (size_t)(colon - addr);
    if (h[0] == '[') {
        if (hl < 3 || h[hl - 1] != ']')
            return -1;
        h++;
        hl -= 2;
    }
    if (hl >= cap)
        return -1;
    unsigned long p = 0;
    const char *q = colon + 1;
    if (!*q)
        return -1;
    for (; *q; q++) {
        if (*q < '0' || *q > '9' || p > 65535)
            return -1;
        p = p * 10 + (unsigned long)(*q - '0');
    }
    if (p == 0 || p > 65535)
        return -1;
    memcpy(host, h, hl);
    host[hl] = 0;
    *port = (unsigned)p;
    return 0;
}

uint64_t stp_hrw_score(const char *node, size_t node_len, const char *name, size_t name_len)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < node_len; i++)
        h = (h ^ (unsigned char)node[i]) * 0x100000001b3ull;
    h = (h ^ 0u) * 0x100000001b3ull;
    for (size_t i = 0; i < name_len; i++)
        h = (h ^ (unsigned char)name[i]) * 0x100000001b3ull;
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    h ^= h >> 31;
    return h;
}

/* 1 when node a ranks before node b */
static int before(uint64_t sa, const char *a, uint64_t sb, const char *b)
{
    if (sa != sb)
        return sa > sb;
    return strcmp(a, b) < 0;   /* bytewise: strcmp compares as unsigned char */
}

size_t stp_hrw_rank(const char *const *ids, size_t n, const char *name, size_t *order, size_t k)
{
    size_t nl = strlen(name), got = 0;
    if (k > n)
        k = n;
    /* partial selection: k is small (R, or n for a full ranking of a small membership) */
    uint64_t last_s = 0;
    const char *last_id = NULL;
    for (; got < k; got++) {
        size_t best = n;
        uint64_t bs = 0;
        for (size_t i = 0; i < n; i++) {
            uint64_t s = stp_hrw_score(ids[i], strlen(ids[i]), name, nl);
            if (last_id && !before(last_s, last_id, s, ids[i]))
                continue;   /* already taken (ranks at or before the last one taken) */
            if (best == n || before(s, ids[i], bs, ids[best])) {
                best = i;
                bs = s;
            }
        }
        if (best == n)
            break;
        order[got] = best;
        last_s = bs;
        last_id = ids[best];
    }
    return got;
}

int stp_enc_cluster_reply(stp_buf *b, uint32_t reqid, const stp_cluster_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_CLUSTER, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->epoch);
    stp_put_u8(b, r->replicas);
    stp_put_u8(b, r->write_quorum);
    stp_put_u8(b, r->flags);
    stp_put_u8(b, 0);
    stp_put_str(b, r->self_id);
    stp_put_u32(b, r->count);
    for (uint32_t i = 0; i < r->count; i++) {
        stp_put_u16(b, r->nodes[i].id_len);
        stp_put_bytes(b, r->nodes[i].id, r->nodes[i].id_len);
        stp_put_u16(b, r->nodes[i].addr_len);
        stp_put_bytes(b, r->nodes[i].addr, r->nodes[i].addr_len);
    }
    return stp_frame_end(b, at);
}

/* one entry at rd; 0 or -1 (malformed) */
static int get_node(stp_rd *rd, stp_cluster_node *e)
{
    e->id_len = stp_get_u16(rd);
    e->id = (const char *)stp_rd_take(rd, e->id_len);
    e->addr_len = stp_get_u16(rd);
    e->addr = (const char *)stp_rd_take(rd, e->addr_len);
    if (rd->bad || stp_node_id_check(e->id, e->id_len) != 0 || e->addr_len == 0 ||
        e->addr_len > STP_MAX_NODE_ADDR || memchr(e->addr, 0, e->addr_len))
        return -1;
    return 0;
}

int stp_dec_cluster_reply(const uint8_t *body, size_t len, stp_cluster_reply *r,
                          const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    memset(r, 0, sizeof *r);
    r->epoch = stp_get_u64(&rd);
    r->replicas = stp_get_u8(&rd);
    r->write_quorum = stp_get_u8(&rd);
    r->flags = stp_get_u8(&rd);
    (void)stp_get_u8(&rd);
    stp_get_str(&rd, r->self_id, sizeof r->self_id);
    r->count = stp_get_u32(&rd);
    if (rd.bad || r->count > STP_MAX_NODES) {
        if (why)
            *why = "CLUSTER: truncated head or too many nodes";
        return STP_S_BAD_REQUEST;
    }
    r->raw = rd.p + rd.off;
    r->raw_len = stp_rd_left(&rd);
    for (uint32_t i = 0; i < r->count; i++) {
        stp_cluster_node e;
        if (get_node(&rd, &e) != 0) {
            if (why)
                *why = "CLUSTER: bad node entry";
            return STP_S_BAD_REQUEST;
        }
    }
    if (stp_rd_left(&rd) != 0) {
        if (why)
            *why = "CLUSTER: trailing bytes after the last field";
        return STP_S_BAD_REQUEST;
    }
    return 0;
}

int stp_cluster_next(const stp_cluster_reply *r, size_t *pos, stp_cluster_node *e)
{
    if (*pos >= r->raw_len)
        return 0;
    stp_rd rd;
    stp_rd_init(&rd, r->raw + *pos, r->raw_len - *pos);
    if (get_node(&rd, e) != 0)
        return 0;
    *pos += rd.off;
    return 1;
}
