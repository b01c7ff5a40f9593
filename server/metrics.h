/* server/metrics.h - seamtexd's Prometheus endpoint: --metrics-listen serves GET /metrics in
 * the Prometheus text exposition format, version 0.0.4 (docs/daemon.md "Metrics").
 *
 *   metrics_http.c   the endpoint: its own thread and poll(2) loop on its own listening
 *                    socket, a minimal HTTP/1.x reader that answers exactly GET (and HEAD)
 *                    /metrics and refuses everything else with a 4xx; bounded request size,
 *                    time and connections. It never touches the I/O threads or their
 *                    connections, so a hostile scraper cannot slow the data path.
 *   metrics_req.c    the request reader (sts_metrics_judge), fuzzed by tests/fuzz/fuzz_metrics.c.
 *   metrics_text.c   the rendering: every STATS entry (sts_stats_collect, h_basic.c) as a
 *                    metric with HELP and TYPE, plus the per-opcode, per-query-mode and cold
 *                    sample histograms read from the same counters STATS reads. No counter is
 *                    kept twice.
 *
 * Ownership: the sts_metrics lives inside the sts_server; the listening socket is opened by
 * sts_metrics_open (at init, so a bad address fails the start), the thread runs from
 * sts_metrics_start to sts_metrics_stop, sts_metrics_close closes the socket.
 */
#ifndef STS_METRICS_H
#define STS_METRICS_H

#include <pthread.h>
#include <stdint.h>

#include "proto.h"

/* Limits of the endpoint (metrics_http.c). */
#define STS_METRICS_MAX_REQUEST  8192   /* request line + headers; past it 431 (414 for the line) */
#define STS_METRICS_DEADLINE_MS  5000   /* from accept to the response's last byte */
#define STS_METRICS_MAX_CONNS    16     /* at once; a newcomer past it closes the oldest */

typedef struct sts_metrics {
    int       fd;          /* listening socket; -1 when off */
    int       port;        /* bound port; 0 when off */
    int       wakefd;      /* eventfd that stops the thread; -1 before start */
    int       started;
    pthread_t thread;
    uint64_t  scrapes;     /* atomic: GET / HEAD /metrics answered 200 */
    uint64_t  refused;     /* atomic: requests answered 4xx, or closed (deadline, eviction,
                              peer gone before a whole request) */
} sts_metrics;

struct sts_server;

/* Opens the listening socket when cfg.metrics_listen is set; 0 (also when off) or -1
 * (logged). */
int sts_metrics_open(struct sts_server *srv);
/* Starts the endpoint's thread (nothing when off); 0 or -1. */
int sts_metrics_start(struct sts_server *srv);
/* Stops and joins the thread, closes its connections. */
void sts_metrics_stop(struct sts_server *srv);
/* Closes the listening socket. */
void sts_metrics_close(struct sts_server *srv);

/* Judges the len request bytes read so far (len <= STS_METRICS_MAX_REQUEST; metrics_req.c):
 * 0 = a whole request is not there yet, else the status to answer: 200 for GET / HEAD
 * /metrics (*head set to 1 for HEAD, else 0), 400, 404, 405, 414 or 431. */
int sts_metrics_judge(const char *buf, size_t len, int *head);

/* Appends the whole exposition (text format 0.0.4) to out. 0, or -1 when out could not grow. */
int sts_metrics_render(struct sts_server *srv, stp_buf *out);

#endif
