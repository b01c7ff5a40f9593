/* server/workers.c - the worker pool for heavy requests.
 *
 * Owns: a FIFO of tasks under one mutex + condition variable, the worker threads, the
 * request deadline (a task that waited longer than deadline-ms, or than the client's own
 * timeout hint, is answered TIMEOUT without running). Does not own: the connection (the reply
 * goes back to its I/O thread through sts_io_complete), what the handler does.
 * Each worker has its own sampling scratch.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "server.h"

typedef struct worker_arg {
    sts_server *srv;
    sts_pool   *pool;
} worker_arg;

static void *worker_main(void *arg)
{
    worker_arg wa = *(worker_arg *)arg;
    free(arg);
    sts_server *srv = wa.srv;
    sts_pool *p = wa.pool;
    sts_scratch scratch;
    memset(&scratch, 0, sizeof scratch);
    for (;;) {
        pthread_mutex_lock(&p->mu);
        while (!p->head && !p->stop)
            pthread_cond_wait(&p->cv, &p->mu);
        if (!p->head) {
            pthread_mutex_unlock(&p->mu);
            break;
        }
        sts_task *t = p->head;
        p->head = t->next;
        if (!p->head)
            p->tail = NULL;
        p->queued--;
        pthread_mutex_unlock(&p->mu);

        int64_t now = sts_now_ms();
        uint32_t dl = STS_LIVE(srv, deadline_ms);
        uint32_t hint = t->h.timeout_ms;
        uint32_t limit = dl && hint ? (dl < hint ? dl : hint) : dl ? dl : hint;
        if (limit && now - t->start_ms > (int64_t)limit) {
            STS_STAT_ADD(srv, deadline_expired, 1);
            STS_STAT_ADD(srv, replies_error, 1);
            char msg[96];
            snprintf(msg, sizeof msg, "waited %lld ms for a worker, the deadline is %u ms",
                     (long long)(now - t->start_ms), limit);
            sts_reply_error(&t->out, &t->h, STP_S_TIMEOUT, msg);
        } else {
            sts_ctx ctx = {srv, t->conn, &scratch, t->start_ms};
            t->close = t->hd->fn(&ctx, &t->h, t->body, &t->out) != 0;
            if (stp_buf_avail(&t->out) >= STP_HEADER_SIZE &&
                stp_rd16(stp_buf_head(&t->out) + 12) != STP_S_OK)
                STS_STAT_ADD(srv, replies_error, 1);
        }
        sts_io_complete(t->conn->io, t);
    }
    sts_scratch_free(&scratch);
    return NULL;
}

int sts_pool_start(sts_server *srv, sts_pool *p, uint32_t n)
{
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->cv, NULL);
    p->threads = calloc(n, sizeof *p->threads);
    if (!p->threads)
        return -1;
    for (uint32_t i = 0; i < n; i++) {
        worker_arg *wa = malloc(sizeof *wa);
        if (!wa)
            return -1;
        wa->srv = srv;
        wa->pool = p;
        if (pthread_create(&p->threads[i], NULL, worker_main, wa) != 0) {
            free(wa);
            return -1;
        }
        p->nthreads++;
    }
    return 0;
}

void sts_pool_submit(sts_pool *p, sts_task *t)
{
    t->next = NULL;
    pthread_mutex_lock(&p->mu);
    if (p->tail)
        p->tail->next = t;
    else
        p->head = t;
    p->tail = t;
    p->queued++;
    pthread_cond_signal(&p->cv);
    pthread_mutex_unlock(&p->mu);
}

/* Workers finish what is queued, then exit. */
void sts_pool_stop(sts_pool *p)
{
    if (!p->threads)
        return;
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    for (uint32_t i = 0; i < p->nthreads; i++)
        pthread_join(p->threads[i], NULL);
    free(p->threads);
    p->threads = NULL;
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->cv);
}
