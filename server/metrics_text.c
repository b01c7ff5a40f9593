/* server/metrics_text.c - the Prometheus text exposition (format 0.0.4) of seamtexd's STATS
 * counters (metrics.h).
 *
 * Owns: metric names, types and help texts, and turning the counters into lines. Does not
 * own: any counter. Scalars come from sts_stats_collect (h_basic.c), the very entries STATS
 * sends, looked up by their STATS key in the table below; histograms and labelled families
 * are read from the structures STATS reads (opstats.c, budget.c, sts_stats.queries_by)
 * through the same accessors. So a scrape and a STATS taken at the same moment agree, and a
 * STATS key added later (without a row here) still appears, as seamtex_stat_<key> (untyped).
 *
 * Names follow Prometheus' conventions: the seamtex_ prefix, base units (seconds, bytes),
 * _total on counters, one HELP and one TYPE line per family, a family's samples together.
 * STATS keys not rendered on purpose: req_<op> (requests counted when parsed; the family
 * seamtex_requests_total counts them when answered), op_<op>_p50_us / _p99_us (Prometheus
 * computes quantiles from the histogram), op_<op>_* and cold_first_us_* (rendered as the
 * histograms), queries and queries_<mode>_<filter> (rendered as seamtex_queries_total by mode
 * and filter, whose sum is `queries`), io<i>_* (rendered as seamtex_io_thread_* by thread),
 * metrics_port.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "h_basic.h"
#include "metrics.h"
#include "server.h"

enum { M_COUNTER, M_GAUGE };

/* One STATS key as one sample of a family; rows of one family are adjacent. */
typedef struct mrow {
    const char *key;     /* STATS key */
    const char *name;    /* metric family */
    int         type;
    const char *label;   /* "" or label="value" for this sample */
    double      scale;   /* 0: the integer as is; else value * scale */
    const char *help;    /* on the family's first row */
} mrow;

static const mrow ROWS[] = {
    {"uptime_ms", "seamtex_uptime_seconds", M_GAUGE, "", 1e-3, "Seconds since the server started."},
    {"conns_current", "seamtex_connections", M_GAUGE, "", 0, "Client connections open now."},
    {"conns_accepted", "seamtex_connections_accepted_total", M_COUNTER, "", 0,
     "Client connections accepted and served."},
    {"conns_rejected", "seamtex_connections_rejected_total", M_COUNTER, "", 0,
     "Connections refused at accept (over max-conns, stopping, out of memory)."},
    {"conns_closed", "seamtex_connections_closed_total", M_COUNTER, "", 0,
     "Served connections closed, for any reason."},
    {"conns_idle_closed", "seamtex_connections_idle_closed_total", M_COUNTER, "", 0,
     "Connections closed by the idle timeout."},
    {"conns_request_timeout", "seamtex_connections_request_timeout_total", M_COUNTER, "", 0,
     "Connections closed because a request frame did not arrive within request-timeout."},
    {"conns_evicted", "seamtex_connections_evicted_total", M_COUNTER, "", 0,
     "Slow connections closed to make room for a new one at max-conns."},
    {"requests", "seamtex_requests_dispatched_total", M_COUNTER, "", 0,
     "Request frames dispatched (counted when parsed, refused ones included)."},
    {"replies_error", "seamtex_replies_error_total", M_COUNTER, "", 0,
     "Replies whose status is not OK, refusals before dispatch included."},
    {"bytes_in", "seamtex_network_receive_bytes_total", M_COUNTER, "", 0,
     "Bytes read from client sockets."},
    {"bytes_out", "seamtex_network_transmit_bytes_total", M_COUNTER, "", 0,
     "Bytes written to client sockets."},
    {"reads", "seamtex_socket_reads_total", M_COUNTER, "", 0, "Socket reads that returned data."},
    {"writes", "seamtex_socket_writes_total", M_COUNTER, "", 0, "Socket writes that sent data."},
    {"frames_bad_magic", "seamtex_frames_refused_total", M_COUNTER, "reason=\"bad_magic\"", 0,
     "Frames refused before dispatch, by reason."},
    {"frames_bad_version", "seamtex_frames_refused_total", M_COUNTER, "reason=\"bad_version\"", 0, NULL},
    {"frames_too_large", "seamtex_frames_refused_total", M_COUNTER, "reason=\"too_large\"", 0, NULL},
    {"frames_unknown_opcode", "seamtex_frames_refused_total", M_COUNTER,
     "reason=\"unknown_opcode\"", 0, NULL},
    {"mem_rejected", "seamtex_frames_refused_total", M_COUNTER, "reason=\"max_memory\"", 0, NULL},
    {"bad_requests", "seamtex_bad_requests_total", M_COUNTER, "", 0,
     "Requests with the REPLY flag set."},
    {"perm_denied", "seamtex_permission_denied_total", M_COUNTER, "", 0,
     "Mutating requests refused for want of the token."},
    {"deadline_expired", "seamtex_deadline_expired_total", M_COUNTER, "", 0,
     "Requests answered TIMEOUT after waiting for a worker past their deadline."},
    {"backpressure_pauses", "seamtex_backpressure_pauses_total", M_COUNTER, "", 0,
     "Times a connection stopped being read because its unsent replies passed conn-out-cap."},
    {"worker_tasks", "seamtex_tasks_total", M_COUNTER, "where=\"worker\"", 0,
     "Requests served, by where they ran."},
    {"inline_tasks", "seamtex_tasks_total", M_COUNTER, "where=\"inline\"", 0, NULL},
    {"query_errors", "seamtex_query_errors_total", M_COUNTER, "", 0,
     "Sampled queries whose per-query status was not OK."},
    {"uploads_begun", "seamtex_uploads_begun_total", M_COUNTER, "", 0, "Fresh uploads started."},
    {"uploads_committed", "seamtex_uploads_committed_total", M_COUNTER, "", 0,
     "Uploads that created or replaced a set."},
    {"uploads_failed", "seamtex_uploads_failed_total", M_COUNTER, "", 0,
     "Upload commits that failed."},
    {"uploads_resumed", "seamtex_uploads_resumed_total", M_COUNTER, "", 0,
     "Kept uploads taken over by UPLOAD_BEGIN with RESUME."},
    {"uploads_expired", "seamtex_uploads_expired_total", M_COUNTER, "", 0,
     "Kept uploads dropped (upload-keep passed, or max-uploads reached)."},
    {"native_write_failed", "seamtex_native_write_failed_total", M_COUNTER, "", 0,
     "Data-dir commits that went on without the set's native file (logged as WARN)."},
    {"upload_bytes", "seamtex_upload_receive_bytes_total", M_COUNTER, "", 0,
     "Bytes accepted in upload chunks."},
    {"deletes", "seamtex_deletes_total", M_COUNTER, "", 0, "Sets deleted."},
    {"jobs_started", "seamtex_jobs_started_total", M_COUNTER, "", 0, "Compress jobs accepted."},
    {"jobs_done", "seamtex_jobs_finished_total", M_COUNTER, "state=\"done\"", 0,
     "Compress jobs finished, by final state."},
    {"jobs_failed", "seamtex_jobs_finished_total", M_COUNTER, "state=\"failed\"", 0, NULL},
    {"jobs_canceled", "seamtex_jobs_finished_total", M_COUNTER, "state=\"canceled\"", 0, NULL},
    {"fetches", "seamtex_fetches_total", M_COUNTER, "", 0, "FETCH_OPENs that succeeded."},
    {"fetches_refused", "seamtex_fetches_refused_total", M_COUNTER, "", 0,
     "FETCH_OPENs refused for memory (max-memory, conn-fetch-cap)."},
    {"fetch_memory", "seamtex_fetch_memory_bytes", M_GAUGE, "", 0, "Bytes of open fetches now."},
    {"buffer_memory", "seamtex_buffer_memory_bytes", M_GAUGE, "", 0,
     "Bytes of connection input and output buffers now."},
    {"shm_attached", "seamtex_shm_attached_total", M_COUNTER, "", 0,
     "Shared-memory regions attached by Unix clients (SHM_ATTACH answered OK)."},
    {"shm_refused", "seamtex_shm_refused_total", M_COUNTER, "", 0,
     "SHM_ATTACH requests refused."},
    {"shm_maps", "seamtex_shm_regions", M_GAUGE, "", 0, "Shared-memory regions mapped now."},
    {"shm_bytes", "seamtex_shm_region_bytes", M_GAUGE, "", 0,
     "Bytes of the shared-memory regions mapped now."},
    {"shm_requests", "seamtex_shm_requests_total", M_COUNTER, "", 0,
     "SAMPLE requests answered through a shared-memory region."},
    {"shm_too_small", "seamtex_shm_reply_too_small_total", M_COUNTER, "", 0,
     "Shared-memory SAMPLE requests whose reply did not fit the room given."},
    {"shm_fds_dropped", "seamtex_shm_fds_dropped_total", M_COUNTER, "", 0,
     "Descriptors closed on receipt: a connection held 4 no SHM_ATTACH had taken."},
    {"shm_overlap_copies", "seamtex_shm_overlap_copies_total", M_COUNTER, "", 0,
     "Shared-memory SAMPLEs whose queries were copied first (reply room overlapping them)."},
    {"sets", "seamtex_sets", M_GAUGE, "", 0, "Texture sets held now."},
    {"set_memory", "seamtex_set_memory_bytes", M_GAUGE, "", 0,
     "Bytes the sets hold in memory now (the sum of LIST's memory)."},
    {"io_threads", "seamtex_io_threads", M_GAUGE, "", 0, "I/O threads."},
    {"workers", "seamtex_workers", M_GAUGE, "", 0, "Worker threads."},
    {"worker_queue", "seamtex_worker_queue", M_GAUGE, "", 0, "Requests waiting for a worker now."},
    {"split_batches", "seamtex_split_batches_total", M_COUNTER, "", 0,
     "SAMPLE batches sampled in parts with idle workers."},
    {"parts_helped", "seamtex_split_parts_helped_total", M_COUNTER, "", 0,
     "Parts of split batches sampled by a worker."},
    {"helpers_yielded", "seamtex_split_helpers_yielded_total", M_COUNTER, "", 0,
     "Workers that left a split batch with parts left because every CPU was sampling."},
    {"memory_budget", "seamtex_memory_budget_bytes", M_GAUGE, "", 0,
     "The memory-budget setting (0 = unlimited)."},
    {"stored_bytes", "seamtex_stored_bytes", M_GAUGE, "", 0,
     "Bytes the sets hold: mapped native files, heap sets, built Ptex tables."},
    {"resident_bytes", "seamtex_resident_bytes", M_GAUGE, "", 0,
     "Of the stored bytes, those in memory now."},
    {"budget_releases", "seamtex_budget_releases_total", M_COUNTER, "", 0,
     "Sets released because resident memory passed the budget."},
    {"budget_released_bytes", "seamtex_budget_released_bytes_total", M_COUNTER, "", 0,
     "Resident bytes those releases let go."},
    {"major_faults", "seamtex_major_page_faults_total", M_COUNTER, "", 0,
     "Major page faults of the daemon since start."},
    {"cold_batches", "seamtex_cold_batches_total", M_COUNTER, "", 0,
     "SAMPLE batches whose set had been released."},
    {"cold_queries", "seamtex_cold_queries_total", M_COUNTER, "", 0,
     "Queries of those batches."},
    {"max_conns", "seamtex_max_connections", M_GAUGE, "", 0, "The max-conns limit."},
    {"max_frame", "seamtex_max_frame_bytes", M_GAUGE, "", 0, "The max-frame limit."},
    {"metrics_scrapes", "seamtex_metrics_scrapes_total", M_COUNTER, "", 0,
     "GET or HEAD /metrics requests answered 200."},
    {"metrics_refused", "seamtex_metrics_refused_total", M_COUNTER, "", 0,
     "Requests to the metrics port refused with a 4xx or closed unanswered."},
    /* a cluster node's (cluster_node.c, docs/cluster.md) */
    {"cluster_members", "seamtex_cluster_members", M_GAUGE, "", 0,
     "Nodes in the cluster as this node sees it."},
    {"cluster_epoch", "seamtex_cluster_membership_epoch", M_GAUGE, "", 0,
     "Version of this node's membership view (grows with every change)."},
    {"cluster_catalogue_sets", "seamtex_cluster_catalogue_sets", M_GAUGE, "", 0,
     "Sets in this node's catalogue snapshot."},
    {"cluster_etcd_ok", "seamtex_cluster_etcd_up", M_GAUGE, "", 0,
     "1 when this node's last etcd call succeeded."},
    {"cluster_etcd_errors", "seamtex_cluster_etcd_errors_total", M_COUNTER, "", 0,
     "etcd calls that failed (unreachable)."},
    {"cluster_lease_grants", "seamtex_cluster_lease_grants_total", M_COUNTER, "", 0,
     "etcd leases granted to this node (1 + re-registrations)."},
    {"cluster_lease_renewals", "seamtex_cluster_lease_renewals_total", M_COUNTER, "", 0,
     "Lease keepalives sent."},
    {"cluster_membership_changes", "seamtex_cluster_membership_changes_total", M_COUNTER, "", 0,
     "Changes of the membership this node saw."},
    {"cluster_repair_passes", "seamtex_cluster_repair_passes_total", M_COUNTER, "", 0,
     "Repair passes over the catalogue."},
    {"cluster_copies_pushed", "seamtex_cluster_copies_pushed_total", M_COUNTER, "", 0,
     "Copies this node pushed to other nodes."},
    {"cluster_copies_received", "seamtex_cluster_copies_received_total", M_COUNTER, "", 0,
     "Copies other nodes pushed to this node."},
    {"cluster_copies_dropped", "seamtex_cluster_copies_dropped_total", M_COUNTER, "", 0,
     "Local copies dropped (stale, extra or deleted)."},
    {"cluster_push_failures", "seamtex_cluster_push_failures_total", M_COUNTER, "", 0,
     "Pushes that failed."},
    {"cluster_push_bytes", "seamtex_cluster_push_bytes_total", M_COUNTER, "", 0,
     "Bytes of the copies pushed."},
    {"cluster_moved", "seamtex_cluster_moved_total", M_COUNTER, "", 0,
     "Requests answered MOVED."},
    {"cluster_refused_unavailable", "seamtex_cluster_refused_unavailable_total", M_COUNTER, "", 0,
     "Writes refused UNAVAILABLE (etcd unreachable or write quorum not reached)."},
    {"cluster_under_replicated", "seamtex_cluster_under_replicated_sets", M_GAUGE, "", 0,
     "Sets with fewer current copies than replicas, as of the last repair pass."},
    {"cluster_claims", "seamtex_cluster_claims_total", M_COUNTER, "", 0,
     "Names claimed in etcd by this node's writes."},
    {"cluster_claims_lost", "seamtex_cluster_claims_lost_total", M_COUNTER, "", 0,
     "Claims that lost to another content (EXISTS)."},
    {"cluster_in_doubt", "seamtex_cluster_write_in_doubt", M_GAUGE, "", 0,
     "1 while a write of this node awaits etcd's word on whether it applied."},
    {"cluster_writes_in_doubt", "seamtex_cluster_writes_in_doubt_total", M_COUNTER, "", 0,
     "Writes whose etcd transaction got no answer."},
    {"cluster_doubts_undone", "seamtex_cluster_doubts_undone_total", M_COUNTER, "", 0,
     "Writes refused UNAVAILABLE that etcd applied later, undone."},
    {"cluster_reads_unconfirmed", "seamtex_cluster_reads_unconfirmed_total", M_COUNTER, "", 0,
     "Reads of a local copy the catalogue had not confirmed, answered MOVED or NOT_FOUND."},
    {"cluster_copies_staged", "seamtex_cluster_copies_staged_total", M_COUNTER, "", 0,
     "Uploads this node took whose copy it staged until the write was recorded."},
    {"cluster_staged_published", "seamtex_cluster_staged_published_total", M_COUNTER, "", 0,
     "Staged copies published once their write was recorded."},
    {"cluster_staged_dropped", "seamtex_cluster_staged_dropped_total", M_COUNTER, "", 0,
     "Staged copies dropped: their write was refused or abandoned."},
    {"cluster_copies_hidden", "seamtex_cluster_copies_hidden_total", M_COUNTER, "", 0,
     "Local copies hidden from reads by a DELETE this node could not record."},
    {"cluster_sets_rerecorded", "seamtex_cluster_sets_rerecorded_total", M_COUNTER, "", 0,
     "Local sets recorded again in a catalogue that had lost them (etcd's data lost)."},
    {"cluster_pushes_backed_off", "seamtex_cluster_pushes_backed_off_total", M_COUNTER, "", 0,
     "Repair pushes not tried: a recent failure's backoff had not run out."},
    {"cluster_etcd_went_back", "seamtex_cluster_etcd_went_back_total", M_COUNTER, "", 0,
     "Times etcd answered with a revision below one this node had seen (restored from an "
     "older snapshot): its sets recorded again, nothing dropped."},
    {"cluster_advertise_ok", "seamtex_cluster_advertise_ok", M_GAUGE, "", 0,
     "1 when this node's --advertise address reached this node at the last check, else 0."},
};
#define NROWS (sizeof ROWS / sizeof ROWS[0])

/* STATS keys (or prefixes, ending in '*') rendered by the structured families below or left
 * out on purpose (see the top of the file). */
static const char *const STRUCTURED[] = {
    "req_*", "op_*", "cold_first_us_*", "queries", "queries_*", "metrics_port",
};

static int structured(const char *key)
{
    unsigned i;
    char rest[16];
    if (sscanf(key, "io%u_%15s", &i, rest) == 2)   /* io<i>_*: render_io's families */
        return 1;
    for (size_t i = 0; i < sizeof STRUCTURED / sizeof STRUCTURED[0]; i++) {
        const char *p = STRUCTURED[i];
        size_t n = strlen(p);
        if (p[n - 1] == '*' ? !strncmp(key, p, n - 1) : !strcmp(key, p))
            return 1;
    }
    return 0;
}

static void out_printf(stp_buf *out, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void out_printf(stp_buf *out, const char *fmt, ...)
{
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (n > 0)
        stp_put_bytes(out, line, (size_t)n < sizeof line ? (size_t)n : sizeof line - 1);
}

static void family(stp_buf *out, const char *name, const char *type, const char *help)
{
    /* help texts are ours: no backslash or newline to escape */
    out_printf(out, "# HELP %s %s\n# TYPE %s %s\n", name, help, name, type);
}

/* A sample's value in seconds from microseconds, exactly (no rounding of whole microseconds). */
static void put_seconds_us(stp_buf *out, uint64_t us)
{
    out_printf(out, "%llu.%06llu", (unsigned long long)(us / 1000000),
               (unsigned long long)(us % 1000000));
}

static const stp_stat *find(const stp_stat *s, size_t n, const char *key)
{
    for (size_t i = 0; i < n; i++)
        if (!strcmp(s[i].key, key))
            return &s[i];
    return NULL;
}

static void render_rows(stp_buf *out, const stp_stat *s, size_t n)
{
    const char *prev = "";
    for (size_t r = 0; r < NROWS; r++) {
        const mrow *m = &ROWS[r];
        const stp_stat *e = find(s, n, m->key);
        if (strcmp(prev, m->name) != 0) {
            /* the first row of a family carries its help */
            family(out, m->name, m->type == M_COUNTER ? "counter" : "gauge", m->help);
            prev = m->name;
        }
        if (!e)
            continue;   /* a key this build's STATS does not send (none today) */
        double v = e->type == STP_STAT_U64 ? (double)e->v.u : e->v.f;
        if (m->label[0])
            out_printf(out, "%s{%s} ", m->name, m->label);
        else
            out_printf(out, "%s ", m->name);
        if (m->scale)
            out_printf(out, "%.3f\n", v * m->scale);
        else if (e->type == STP_STAT_U64)
            out_printf(out, "%llu\n", (unsigned long long)e->v.u);
        else
            out_printf(out, "%.17g\n", v);
    }
}

/* STATS keys with no row: seamtex_stat_<key>, untyped (a key added to STATS later shows up
 * before it gets a proper name). */
static void render_rest(stp_buf *out, const stp_stat *s, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (structured(s[i].key))
            continue;
        size_t r = 0;
        while (r < NROWS && strcmp(ROWS[r].key, s[i].key) != 0)
            r++;
        if (r < NROWS)
            continue;
        char name[STP_MAX_STAT_KEY + 16];
        snprintf(name, sizeof name, "seamtex_stat_%s", s[i].key);
        for (char *p = name; *p; p++)       /* keys are snake_case; keep the name legal */
            if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
                  (*p >= '0' && *p <= '9') || *p == '_'))
                *p = '_';
        char help[STP_MAX_STAT_KEY + 48];
        snprintf(help, sizeof help, "STATS key %s (PROTOCOL.md 4.7).", name + 13);
        family(out, name, "untyped", help);
        if (s[i].type == STP_STAT_U64)
            out_printf(out, "%s %llu\n", name, (unsigned long long)s[i].v.u);
        else
            out_printf(out, "%s %.17g\n", name, s[i].v.f);
    }
}

/* The per-I/O-thread STATS keys io<i>_conns, io<i>_accepted and io<i>_cpu (with --pin-io) as
 * three families labelled thread="<i>"; a family none of whose keys is sent (io_cpu without
 * pin-io) is left out. */
static void render_io(stp_buf *out, const stp_stat *s, size_t n)
{
    static const struct {
        const char *suffix, *name, *type, *help;
    } FAM[] = {
        {"conns", "seamtex_io_thread_connections", "gauge",
         "Client connections open now, by the I/O thread serving them."},
        {"accepted", "seamtex_io_thread_accepted_total", "counter",
         "Connections handed to each I/O thread since start."},
        {"cpu", "seamtex_io_thread_cpu", "gauge",
         "The CPU each I/O thread is pinned to (pin-io yes)."},
    };
    for (size_t f = 0; f < sizeof FAM / sizeof FAM[0]; f++) {
        int any = 0;
        for (size_t k = 0; k < n; k++) {
            unsigned i;
            char suf[16];
            if (sscanf(s[k].key, "io%u_%15s", &i, suf) != 2 || strcmp(suf, FAM[f].suffix) ||
                s[k].type != STP_STAT_U64)
                continue;
            if (!any++)
                family(out, FAM[f].name, FAM[f].type, FAM[f].help);
            out_printf(out, "%s{thread=\"%u\"} %llu\n", FAM[f].name, i,
                       (unsigned long long)s[k].v.u);
        }
    }
}

static void lower(const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%s", name);
    for (char *p = out; *p; p++)
        if (*p >= 'A' && *p <= 'Z')
            *p = (char)(*p - 'A' + 'a');
}

static void render_opcodes(stp_buf *out, sts_server *srv)
{
    static const char *const fam[3] = {"seamtex_requests_total", "seamtex_request_errors_total",
                                       "seamtex_request_duration_seconds"};
    static const char *const help[3] = {
        "Requests answered, by opcode (counted when the reply is queued).",
        "Of those, replies whose status is not OK, by opcode.",
        "Time from a request parsed to its reply queued, by opcode."};
    for (int f = 0; f < 3; f++) {
        family(out, fam[f], f == 2 ? "histogram" : "counter", help[f]);
        for (unsigned op = 0; op < 256; op++) {
            const char *name = stp_opcode_name(op);
            if (!name)
                continue;
            char lo[32];
            lower(name, lo, sizeof lo);
            uint64_t lat[STS_LAT_BUCKETS], errors, sum_us;
            uint64_t total = sts_opstats_read(&srv->opstats, op, lat, &errors, &sum_us);
            if (f == 0) {
                out_printf(out, "%s{opcode=\"%s\"} %llu\n", fam[f], lo, (unsigned long long)total);
                continue;
            }
            if (f == 1) {
                out_printf(out, "%s{opcode=\"%s\"} %llu\n", fam[f], lo,
                           (unsigned long long)errors);
                continue;
            }
            uint64_t cum = 0;
            for (unsigned b = 0; b < STS_LAT_BUCKETS; b++) {
                cum += lat[b];
                out_printf(out, "seamtex_request_duration_seconds_bucket{opcode=\"%s\",le=\"", lo);
                if (b == STS_LAT_BUCKETS - 1)
                    out_printf(out, "+Inf");
                else
                    put_seconds_us(out, sts_opstats_bucket_hi_us(b));
                out_printf(out, "\"} %llu\n", (unsigned long long)cum);
            }
            out_printf(out, "seamtex_request_duration_seconds_sum{opcode=\"%s\"} ", lo);
            put_seconds_us(out, sum_us);
            out_printf(out, "\nseamtex_request_duration_seconds_count{opcode=\"%s\"} %llu\n", lo,
                       (unsigned long long)cum);
        }
    }
}

static void render_queries(stp_buf *out, sts_server *srv)
{
    family(out, "seamtex_queries_total", "counter",
           "SAMPLE and SAMPLE_DIR queries answered, by sampling mode and filter.");
    for (unsigned m = 0; m < STS_QMODES; m++)
        for (unsigned f = 0; f < STS_QFILTERS; f++) {
            const char *mn = stp_mode_name(m), *fn = stp_filter_name(f);
            if (!mn || !fn)
                continue;
            out_printf(out, "seamtex_queries_total{mode=\"%s\",filter=\"%s\"} %llu\n", mn, fn,
                       (unsigned long long)__atomic_load_n(&srv->stats.queries_by[m][f],
                                                           __ATOMIC_RELAXED));
        }
}

static void render_cold(stp_buf *out, sts_server *srv)
{
    uint64_t counts[STS_COLD_HIST], sum_us, cum = 0;
    uint32_t bound_us[STS_COLD_HIST];
    sts_budget_hist(srv, counts, bound_us, &sum_us);
    family(out, "seamtex_cold_batch_duration_seconds", "histogram",
           "Sampling time of SAMPLE batches whose set had been released (faulted back in).");
    for (unsigned k = 0; k < STS_COLD_HIST; k++) {
        cum += counts[k];
        out_printf(out, "seamtex_cold_batch_duration_seconds_bucket{le=\"");
        if (bound_us[k] == UINT32_MAX)
            out_printf(out, "+Inf");
        else
            put_seconds_us(out, bound_us[k]);
        out_printf(out, "\"} %llu\n", (unsigned long long)cum);
    }
    out_printf(out, "seamtex_cold_batch_duration_seconds_sum ");
    put_seconds_us(out, sum_us);
    out_printf(out, "\nseamtex_cold_batch_duration_seconds_count %llu\n", (unsigned long long)cum);
}

int sts_metrics_render(sts_server *srv, stp_buf *out)
{
    size_t cap = sts_stats_max_keys(srv);
    stp_stat *s = malloc(cap * sizeof *s);
    if (!s)
        return -1;
    size_t n = sts_stats_collect(srv, s, cap);
    family(out, "seamtex_build_info", "gauge", "Always 1; the labels say which seamtexd runs.");
    out_printf(out, "seamtex_build_info{version=\"%s\",protocol=\"%d\"} 1\n", STS_VERSION,
               STP_VERSION);
    render_rows(out, s, n);
    render_io(out, s, n);
    render_rest(out, s, n);
    free(s);
    render_queries(out, srv);
    render_opcodes(out, srv);
    render_cold(out, srv);
    return out->err ? -1 : 0;
}
