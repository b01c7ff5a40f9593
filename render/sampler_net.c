/* render/sampler_net.c - seamtex-render's sampler over the daemon: a frame's queries go out as
 * pipelined SAMPLE requests of `batch` queries, up to `inflight` outstanding, on a libseamtex
 * connection the caller owns; replies (in any order: matched by request id) are decoded into
 * the frame's colour array. On a unix: connection it can first attach a shared-memory region
 * sized for that window (rs_net_shm; PROTOCOL.md 4.12): libseamtex then puts each request's
 * queries and reply there and only small frames cross the socket.
 *
 * Owns: the batching, the window, the region's size and the shm policy, the byte counts.
 * Does not own: the connection, the wire, the region's ring (libseamtex).
 */
#include "render.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "unixaddr.h"

#define NET_MAX_INFLIGHT 64

typedef struct net {
    rs_sampler base;
    stc_conn *c;
    char set[256];
    unsigned batch, inflight;
    float *tmp;      /* batch * nchan */
} net;

/* Values of a reply in any output format into nchan floats per query. */
static void to_float(const stc_sample_result *r, float *out)
{
    size_t n = (size_t)r->count * r->nchan;
    if (r->outfmt == STC_OUT_F32)
        memcpy(out, r->values, n * sizeof *out);
    else if (r->outfmt == STC_OUT_UNORM8)
        for (size_t i = 0; i < n; i++)
            out[i] = ((const uint8_t *)r->values)[i] * (1.0f / 255.0f);
    else
        for (size_t i = 0; i < n; i++)
            out[i] = ((const uint16_t *)r->values)[i] * (1.0f / 65535.0f);
}

/* The window rs_net_new uses: batch and inflight (0 = defaults) clamped to the server's
 * limits. */
static void net_window(const stc_server *sv, unsigned *batch, unsigned *inflight)
{
    if (*batch == 0)
        *batch = 16384;
    if (sv->max_batch && *batch > sv->max_batch)
        *batch = sv->max_batch;
    if (*inflight == 0)
        *inflight = 8;
    if (*inflight > NET_MAX_INFLIGHT)
        *inflight = NET_MAX_INFLIGHT;
    if (sv->max_inflight && *inflight > sv->max_inflight)
        *inflight = sv->max_inflight;
}

static int net_sample(rs_sampler *s, const stc_sample_opts *o, const stc_query *q, size_t n,
                      float *out, float *cov, rs_stats *st, char *msg, size_t ml)
{
    net *p = (net *)s;
    stc_sample_opts so = *o;
    so.want = cov ? STC_WANT_COVERAGE : 0;
    size_t nb = (n + p->batch - 1) / p->batch;
    uint32_t ids[NET_MAX_INFLIGHT];
    size_t which[NET_MAX_INFLIGHT];
    int via_shm[NET_MAX_INFLIGHT];
    unsigned nout = 0;
    size_t sent = 0, done = 0;
    size_t vbytes = so.outfmt == STC_OUT_F32 ? 4 : so.outfmt == STC_OUT_UNORM8 ? 1 : 2;
    while (done < nb) {
        while (sent < nb && nout < p->inflight) {
            size_t first = sent * p->batch, k = n - first < p->batch ? n - first : p->batch;
            uint64_t shm0, shm1;
            stc_shm_counts(p->c, &shm0, NULL);
            int rc = stc_append_sample(p->c, p->set, &so, q + first, k, &ids[nout]);
            if (rc != 0) {
                snprintf(msg, ml, "SAMPLE: %s (%s)", stc_strerror(rc), stc_errmsg(p->c));
                stc_discard_pending(p->c);
                return -1;
            }
            stc_shm_counts(p->c, &shm1, NULL);
            via_shm[nout] = shm1 != shm0;   /* the queries went into the region (4.12) */
            which[nout++] = sent++;
            st->bytes_out += 24 + 2 + strlen(p->set) + 24 + (via_shm[nout - 1] ? 24 : 28 * k);
        }
        int rc = stc_flush(p->c);
        stc_reply r;
        if (rc == 0)
            rc = stc_get_reply(p->c, -1, &r);
        if (rc != 0) {
            snprintf(msg, ml, "SAMPLE: %s (%s)", stc_strerror(rc), stc_errmsg(p->c));
            stc_discard_pending(p->c);
            return -1;
        }
        unsigned slot = 0;
        while (slot < nout && ids[slot] != r.reqid)
            slot++;
        if (slot == nout) {
            snprintf(msg, ml, "SAMPLE: a reply to request %u, which is not outstanding", r.reqid);
            stc_discard_pending(p->c);
            return -1;
        }
        size_t b = which[slot];
        int shm = via_shm[slot];
        ids[slot] = ids[nout - 1];
        which[slot] = which[nout - 1];
        via_shm[slot] = via_shm[nout - 1];
        nout--;
        if (r.status != 0) {
            snprintf(msg, ml, "SAMPLE: %s (%s)", stc_strerror(r.status), r.errmsg);
            stc_discard_pending(p->c);
            return -1;
        }
        stc_sample_result res;
        rc = stc_reply_sample(p->c, &r, &res);
        size_t first = b * p->batch, k = n - first < p->batch ? n - first : p->batch;
        if (rc != 0 || res.count != k || res.nchan != s->nchan) {
            snprintf(msg, ml, "SAMPLE reply: %s (count %u for %zu, %u channels for %u)",
                     stc_strerror(rc), res.count, k, res.nchan, s->nchan);
            stc_discard_pending(p->c);
            return -1;
        }
        to_float(&res, p->tmp);
        rs_expand_rgba(p->tmp, s->nchan, k, out + 4 * first);
        if (res.coverage)
            for (size_t j = 0; j < k; j++) {
                if (cov)
                    cov[first + j] = res.coverage[j];
                st->zero_coverage += res.coverage[j] == 0;
            }
        st->bytes_in += 24 + (shm ? 16 : 12 + k * res.nchan * vbytes + (res.coverage ? 4 * k : 0));
        st->batches++;
        st->shm_batches += shm;
        done++;
    }
    st->queries += n;
    return 0;
}

static void net_free(rs_sampler *s)
{
    net *p = (net *)s;
    free(p->tmp);
    free(p);
}

rs_sampler *rs_net_new(stc_conn *c, const char *set, unsigned batch, unsigned inflight,
                       char *msg, size_t ml)
{
    stc_info info;
    int rc = stc_info_get(c, set, 0, 0, &info);
    if (rc != 0) {
        snprintf(msg, ml, "INFO %s: %s (%s)", set, stc_strerror(rc), stc_errmsg(c));
        return NULL;
    }
    net_window(stc_server_info(c), &batch, &inflight);
    net *p = calloc(1, sizeof *p);
    if (!p || strlen(set) >= sizeof p->set) {
        free(p);
        snprintf(msg, ml, "out of memory");
        return NULL;
    }
    p->c = c;
    strcpy(p->set, set);
    p->batch = batch;
    p->inflight = inflight;
    p->base.sample = net_sample;
    p->base.free = net_free;
    p->base.nchan = info.nchan;
    p->base.kind = info.kind;
    p->base.nfaces = info.nfaces;
    p->tmp = malloc((size_t)batch * info.nchan * sizeof *p->tmp);
    if (!p->tmp) {
        net_free(&p->base);
        snprintf(msg, ml, "out of memory");
        return NULL;
    }
    return &p->base;
}

/* The region for `inflight` requests of `batch` queries outstanding at once (as rs_net_new
 * clamps them), plus one for the reply last read in place: libseamtex's own count of what a
 * request takes (its queries, then a reply room of 4 channels with coverage and status). */
static size_t shm_bytes(unsigned batch, unsigned inflight, unsigned outfmt)
{
    return stc_shm_request_bytes(0, batch, outfmt) * (inflight + 1);
}

int rs_net_shm(stc_conn *c, const char *host, int policy, unsigned batch, unsigned inflight,
               unsigned outfmt, char *note, size_t nl, char *msg, size_t ml)
{
    rt_say(note, nl, "%s", "");
    if (policy == RS_SHM_OFF)
        return 0;
    const char *why = NULL;
    if (!stu_is_unix_addr(host))
        why = "the daemon is not on a unix: address";
    else if (!(stc_server_info(c)->caps & STC_CAP_SHM))
        why = "the daemon does not offer it (HELLO capability SHM)";
    if (!why) {
        net_window(stc_server_info(c), &batch, &inflight);
        size_t bytes = shm_bytes(batch, inflight, outfmt);
        int rc = stc_shm_attach(c, bytes);
        if (rc == 0) {
            rt_say(note, nl, "shared memory: %zu bytes for %u requests of %u queries", bytes,
                   inflight, batch);
            return 1;
        }
        if (stc_error(c)) {   /* the connection broke: no socket to fall back to */
            rt_say(msg, ml, "SHM_ATTACH: %s (%s)", stc_strerror(rc), stc_errmsg(c));
            return -1;
        }
        rt_say(note, nl, "the daemon refused %zu bytes: %s", bytes, stc_errmsg(c));
        why = note;
    }
    if (policy == RS_SHM_ON) {
        rt_say(msg, ml, "--shm on: no shared memory: %s", why);
        return -1;
    }
    if (why != note)
        rt_say(note, nl, "%s", why);
    return 0;
}
