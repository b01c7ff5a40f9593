/* server/h_jobs.h - COMPRESS jobs, the job thread and FETCH handles (h_jobs.c).
 *
 * Owns: the COMPRESS, JOB_STATUS, JOB_CANCEL and FETCH_* entries of the dispatch table
 * (sts_handler_fn, dispatch.h: one reply frame appended to the caller's `out`), the job table
 * and thread (srv->jobs), the fetch handles (srv->fetches). Does not own: the handle table
 * code (handles.h), the BC1 encoder and the writers (store/).
 */
#ifndef STS_H_JOBS_H
#define STS_H_JOBS_H

#include <stdint.h>

#include "dispatch.h"

/* Creates srv->jobs and starts the job thread (server start). 0 or -1. */
int sts_jobs_start(sts_server *srv);
/* Cancels running jobs, joins the job thread, frees every job (srv->jobs becomes NULL) and
 * every fetch handle. Safe when start failed or never ran. */
void sts_jobs_stop(sts_server *srv);
/* Drops the fetch handles a connection opened (its I/O thread calls it when it closes). */
void sts_fetch_drop_conn(sts_server *srv, uint64_t conn_id);

STS_HANDLER(sts_h_compress);
STS_HANDLER(sts_h_job_status);
STS_HANDLER(sts_h_job_cancel);
STS_HANDLER(sts_h_fetch_open);
STS_HANDLER(sts_h_fetch_read);
STS_HANDLER(sts_h_fetch_close);

#endif
