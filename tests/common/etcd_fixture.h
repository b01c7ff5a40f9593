/* tests/common/etcd_fixture.h - a real etcd for cluster tests and benchmarks.
 *
 * Owns: starting /usr/bin/etcd (or $SEAMTEX_ETCD) on loopback on two free ports with its data
 * in a mkdtemp dir, waiting until it answers, restarting (its data kept or wiped, or put back
 * from a copy saved earlier: a restored backup), stopping, pausing (SIGSTOP / SIGCONT: "etcd
 * unreachable") and removing it. etcd is a declared dependency (deploy/install-deps.sh): a
 * missing binary fails the start, it is never a skip.
 */
#ifndef ST_ETCD_FIXTURE_H
#define ST_ETCD_FIXTURE_H

#include <sys/types.h>

typedef struct st_etcd {
    pid_t pid;
    int   client_port, peer_port;
    char  dir[256];
    char  url[320];        /* etcd://127.0.0.1:<port>/<prefix> for seamtexd --cluster */
} st_etcd;

/* 0, or -1 with the reason on stderr. prefix: the cluster's key prefix ("/t"). */
int  st_etcd_start(st_etcd *e, const char *prefix);
/* Kills etcd (SIGKILL) and starts it again on the same ports; wipe: with its data dir
 * removed first (an etcd that lost its data: no keys, revisions from 1). 0 or -1. */
int  st_etcd_restart(st_etcd *e, int wipe);
/* A backup and its restore, as `etcdctl snapshot save` / `snapshot restore` give them (the
 * store's revision with it): save kills etcd, copies its data dir aside and starts it again;
 * restore kills it, puts the copy back in place of its data dir and starts it (an etcd gone
 * back to the state, and the revision, of the save; the copy is kept for another restore).
 * 0 or -1. */
int  st_etcd_save(st_etcd *e);
int  st_etcd_restore(st_etcd *e);
/* SIGSTOP (paused) or SIGCONT to etcd; a pause returns once every etcd thread has stopped
 * (st_wait_stopped). 0, or -1 when etcd is not running or did not stop within 10 s. */
int  st_etcd_pause(st_etcd *e, int paused);
/* Kills etcd and removes its dir. */
void st_etcd_stop(st_etcd *e);

#endif
