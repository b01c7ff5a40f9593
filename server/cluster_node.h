/* server/cluster_node.h - seamtexd as a member of a cluster (docs/cluster.md).
 *
 *   cluster_node.c    the sts_cluster: start / stop, the membership thread (lease, keepalive,
 *                     polling nodes/), the view handlers read (membership, catalogue
 *                     snapshot), CLUSTER, MOVED, STATS keys
 *   cluster_repair.c  the repair thread: a pass over the catalogue (push, drop, forget)
 *   cluster_write.c   the write path run by a COMMIT, DELETE or COMPRESS job on its own thread:
 *                     claim, staging (the caller's), pushes, finalize, publishing the staged
 *                     copy / take back and drop it
 *   cluster_fence.c   the write path's transactions and the node's op key: a write whose
 *                     outcome is unknown (etcd did not answer) is fenced and made to match
 *                     the UNAVAILABLE its request was answered with
 *
 * Shared state and its locks (no lock is held across I/O):
 *   cl->mu       guards the view: members[] (sorted by id), epoch, cat[] (catalogue snapshot
 *                of the last repair pass, sorted by name), served[], serve_gen and hidden[]
 *                (the local copies reads may use). Writers: the membership thread (members, epoch), the
 *                repair thread (cat, served, hidden) and the write path (cat; hidden: DELETE). Readers: handlers
 *                (CLUSTER, MOVED, every read of a set), the write path (owners), the repair
 *                thread.
 *   cl->etcd_mu  guards cl->etcd_w, the etcd handle of the write path (workers, job thread),
 *                and the op key's state (op_rev, op_seq, doubt); the membership and repair
 *                threads have their own handles (the membership thread takes etcd_mu, with
 *                trylock, to resolve a write in doubt).
 *   etcd_ok, the counters: atomics.
 * Without --cluster srv->cluster is NULL and none of this runs.
 */
#ifndef STS_CLUSTER_NODE_H
#define STS_CLUSTER_NODE_H

#include <pthread.h>
#include <stdint.h>

#include "catalog.h"
#include "registry.h"
#include "dispatch.h"
#include "etcd.h"
#include "proto.h"
#include "stp_cluster.h"

typedef struct sts_server sts_server;

#define STS_CL_MAX_HOLDERS 16

typedef struct sts_cl_member {
    char     id[STP_MAX_NODE_ID + 1];
    char     addr[STP_MAX_NODE_ADDR + 1];
    uint64_t inc;                        /* its incarnation (0: a node that does not say) */
    int64_t  key_rev;                    /* create_revision of its nodes/ key: new each time
                                            the node registers (a restart, a new lease) */
} sts_cl_member;

typedef struct sts_cl_entry {            /* one set of the catalogue snapshot */
    char     name[STP_MAX_NAME + 1];
    uint32_t crc32;
    int      state;                      /* SCL_SET_* */
    int      nholders;                   /* nodes with a current copy (copies/ keys) */
    char     holders[STS_CL_MAX_HOLDERS][STP_MAX_NODE_ID + 1];
} sts_cl_entry;

typedef struct sts_cl_counters {
    uint64_t etcd_errors, lease_grants, lease_renewals, membership_changes, repair_passes;
    uint64_t copies_pushed, copies_received, copies_dropped, push_failures, push_bytes;
    uint64_t moved, refused_unavailable, under_replicated, claims, claims_lost;
    uint64_t writes_in_doubt, doubts_undone;   /* cluster_fence.c */
    uint64_t reads_unconfirmed;   /* reads of a local copy the catalogue did not confirm */
    uint64_t copies_staged, staged_published, staged_dropped;   /* the write path's copies */
    uint64_t copies_hidden;   /* copies hidden by a DELETE this node could not record */
    uint64_t sets_rerecorded;   /* local sets recorded again after a catalogue loss */
    uint64_t pushes_backed_off;   /* repair pushes not tried: their backoff had not run out */
    uint64_t etcd_went_back;   /* etcd answered with a revision below one seen (cluster_mark.c) */
} sts_cl_counters;

typedef struct sts_cluster {
    sts_server     *srv;
    char            prefix[256];
    char            self[STP_MAX_NODE_ID + 1];
    char            addr[STP_MAX_NODE_ADDR + 1];   /* advertised, port filled in at start */
    unsigned        replicas, quorum;
    uint64_t        inc;               /* this process's incarnation: random, drawn at init */
    int64_t         node_rev;          /* atomic: revision of this process's put of nodes/<id>
                                          (the leave deletes only that one) */
    uint64_t        other_inc;         /* membership thread: another process of this id seen
                                          (logged once) */

    pthread_mutex_t mu;                /* the view, see above */
    sts_cl_member  *members;  size_t nmembers;
    uint64_t        epoch;
    sts_cl_entry   *cat;      size_t ncat;
    /* under mu: the local copies this node serves to reads (docs/cluster.md "Reads and
     * MOVED"): served[] (sorted by name) holds the copies the last repair pass confirmed, by
     * registry generation; a copy published since that pass began (gen >= serve_gen) is
     * served too. Before the first pass serve_gen is the registry's generation at start
     * (after the data dir was loaded) and served[] is empty: no copy from the data dir is
     * served before the catalogue has confirmed it. */
    struct sts_cl_served { char name[STP_MAX_NAME + 1]; uint64_t gen; } *served;
    size_t          nserved;
    uint64_t        serve_gen;
    /* under mu: copies hidden from reads whatever served[] says (sts_cluster_hide: a DELETE
     * this node got but could not record, e.g. forwarded by the node that deleted the set
     * while this one could not reach etcd), by registry generation, each with the value of
     * hide_seq that hid it; a repair pass shows one again only when its catalogue, read after
     * the hide, records the copy's contents (docs/cluster.md "Reads and MOVED") */
    struct sts_cl_hidden { char name[STP_MAX_NAME + 1]; uint64_t gen, seq; } *hidden;
    size_t          nhidden, hidden_cap;
    uint64_t        hide_seq;

    pthread_mutex_t etcd_mu;
    scl_etcd       *etcd_w;            /* write path */
    scl_etcd       *etcd_m;            /* membership thread */
    scl_etcd       *etcd_r;            /* repair thread */
    int64_t         lease;             /* membership thread only */

    int             etcd_ok;           /* atomic: the last etcd call of any thread succeeded */
    int             stop;              /* under wake_mu (set atomically: it is the abort
                                          flag of etcd_m and etcd_r, scl_etcd_set_abort) */
    int             kick;              /* under wake_mu: run a repair pass now */
    int             recheck;           /* atomic: a REPLICA_PUBLISH could not be checked
                                          against etcd (sts_cluster_recheck): kick a repair
                                          pass when etcd answers again */
    pthread_mutex_t wake_mu;
    pthread_cond_t  wake;
    pthread_t       member_thread, repair_thread;
    int             threads;           /* how many were started */
    int64_t         changed_ms;        /* atomic: when the membership last changed (monotonic) */
    /* repair thread only: pending claims seen without their origin (not a member, or a member
     * of another incarnation than the one that claimed), and since when */
    struct sts_cl_orphan { char name[STP_MAX_NAME + 1]; int64_t mod_rev, since_ms; } *orphans;
    size_t          norphans;
    /* repair thread only: local sets the catalogue did not record, and since when (dropped
     * after two lease TTLs: a delete in doubt may be put back meanwhile) */
    struct sts_cl_orphan *gone;
    size_t          ngone;
    /* repair thread only: the repair pushes that failed, per (set contents, target process),
     * each with its consecutive failures and the time before which it is not tried again
     * (docs/cluster.md "Repair and rebalance", backoff) */
    struct sts_cl_backoff {
        char     name[STP_MAX_NAME + 1];
        uint32_t crc;
        char     node[STP_MAX_NODE_ID + 1];
        uint64_t inc;
        int64_t  key_rev;
        unsigned fails;
        int      seen;                   /* wanted by the current pass */
        int64_t  next_ms;                /* monotonic */
    } *backoff;
    size_t          nbackoff, backoff_cap;
    /* the op key (cluster_fence.c), under etcd_mu */
    int64_t         op_rev;            /* mod_revision of ops/<self> as last written or read */
    int             op_known;          /* op_rev has been read since start */
    uint64_t        op_seq;            /* writes sent by this process */
    struct sts_cl_doubt *doubt;        /* the write whose outcome is unknown, or NULL */
    int             in_doubt;          /* atomic: doubt != NULL (a hint for other threads) */
    char            doubt_set[STP_MAX_NAME + 1];   /* under mu: the set of the write in doubt */
    uint64_t        mark_seen;         /* repair thread only: the PREFIX/cluster id the last
                                          sts_cluster_mark_check read (0 none) */
    scl_revwatch    revw;              /* the highest etcd revision the three handles have
                                          seen (seeded from the cluster-id file), and whether
                                          etcd went back below it (etcd.h, cluster_mark.c) */
    int64_t         rev_kept;          /* repair thread only (and init): the revision the
                                          cluster-id file keeps */
    int64_t         pass_rev;          /* repair thread only: the revision of the catalogue
                                          the last sts_cluster_mark_check judged */
    int64_t         keep_top;          /* repair thread only: the watch's highest revision as
                                          of that check: what sts_cluster_rev_keep keeps */
    unsigned        checks_unkept;     /* repair thread only: ordinary passes since
                                          cluster-id was last written */
    int64_t         back_from;         /* repair thread only: etcd went back from this
                                          revision and the catalogue is not adopted yet (the
                                          WARN is logged once), 0 none */
    int             advertise_ok;      /* atomic: the last self-check found this node at its
                                          advertised address (STATS cluster_advertise_ok) */
    int             adv_state;         /* repair thread only: -1 not checked yet, 0 failing,
                                          1 ok (a change is logged) */
    int64_t         adv_next_ms;       /* repair thread only: the next self-check (monotonic) */
    sts_cl_counters n;                 /* atomics */
} sts_cluster;

#define STS_CL_ADD(cl, f, v) __atomic_add_fetch(&(cl)->n.f, (v), __ATOMIC_RELAXED)

/* ---- cluster_node.c ---- */
struct sts_config;
/* The cluster flags' form (--cluster URL, --node-id, --advertise), checked by main before
 * anything starts so that a bad one is a bad flag (exit 2, seamtexd(8)), not a start failure
 * after the data dir was loaded. 0 (also without --cluster), or -1 with err set; prefix (may
 * be NULL) receives the URL's key prefix. */
int  sts_cluster_config_check(const struct sts_config *c, char *prefix, size_t prefix_cap,
                              char *err, size_t errcap);
/* Opens the etcd handles (srv->cluster set); 0 or -1 (logged). Called by sts_server_init. */
int  sts_cluster_init(sts_server *srv);
/* Registers the node (one try; the membership thread retries) and starts both threads. */
int  sts_cluster_start(sts_server *srv);
/* Stops the threads and removes the node's key (a graceful leave). */
void sts_cluster_stop(sts_server *srv);
void sts_cluster_free(sts_server *srv);
int  sts_cluster_etcd_ok(sts_cluster *cl);
/* Marks etcd reachable or not after a call (rc from etcd.h). */
void sts_cluster_note_etcd(sts_cluster *cl, int rc);
/* Copies of the membership: ids[] point into *members (the caller frees *members). */
size_t sts_cluster_members(sts_cluster *cl, sts_cl_member **members, uint64_t *epoch);
/* For a set this node does not hold: 1 and the address of a node to ask (MOVED) in addr; -1
 * and a message in addr (UNAVAILABLE) when the catalogue records the set but no live member
 * holds a copy and this node is one of its owners; 0 when the request is NOT_FOUND here. */
int  sts_cluster_moved(sts_cluster *cl, const char *name, char *addr, size_t cap);
/* Adds or replaces (holders != NULL) or removes (holders NULL) one entry of the snapshot. */
void sts_cluster_note_set(sts_cluster *cl, const char *name, uint32_t crc32,
                          const char (*holders)[STP_MAX_NODE_ID + 1], int nholders);
/* Replaces the catalogue snapshot (takes ownership of cat). */
void sts_cluster_set_catalogue(sts_cluster *cl, sts_cl_entry *cat, size_t n);
/* Replaces the list of confirmed local copies (takes ownership of s, sorted by name) and the
 * generation from which copies are served unconfirmed (the repair pass). */
void sts_cluster_set_served(sts_cluster *cl, struct sts_cl_served *s, size_t n, uint64_t gen);
/* 1 when this node may answer a read from its local copy ref: the built-in set (not from
 * the data dir), a copy the last repair pass confirmed current (its generation in
 * served[]), or one published since that pass began. 0 otherwise: a copy from before a
 * restart that the catalogue has not confirmed yet, one of a set deleted or replaced
 * meanwhile; the read is then answered as for a set the node does not hold. */
int  sts_cluster_serves(sts_cluster *cl, const st_setref *ref);
/* The registry generation served[] confirms for name, 0 for none (generations start at 1).
 * The caller holds mu, or is the repair thread (served[]'s only writer). */
uint64_t sts_cluster_served_gen(const sts_cluster *cl, const char *name);
/* Hides this node's copy of name (the registry's current one, if it is from the data dir)
 * from reads until a repair pass whose catalogue was read after this call records it with
 * the copy's contents; returns the copy's generation, 0 when there is none or no memory
 * (nothing hidden). Called by DELETE before it tries to record the delete. */
uint64_t sts_cluster_hide(sts_cluster *cl, const char *name);
/* 1 when etcd's catalogue records name with contents crc32 (state OK), 0 when it records
 * something else or nothing, < 0 an etcd error (noted). A fresh read (cluster_write.c, under
 * etcd_mu): REPLICA_PUBLISH asks it before hiding a copy (h_upload.c). */
int sts_cluster_records(sts_cluster *cl, const char *name, uint32_t crc32);
/* Shows the copy (name, gen) to reads again if it was hidden by a call that returned a
 * hide_seq <= seq_max (UINT64_MAX: whenever it was hidden). */
void sts_cluster_unhide(sts_cluster *cl, const char *name, uint64_t gen, uint64_t seq_max);
/* The hide_seq of the latest hide (under mu); the repair pass reads it before etcd. */
uint64_t sts_cluster_hide_seq(sts_cluster *cl);
/* The repair pass: forgets the hidden copies hidden by hide_seq <= seq_max that the registry
 * no longer holds (deleted or replaced since). */
void sts_cluster_hidden_prune(sts_cluster *cl, uint64_t seq_max);
/* The registry lookup of the read requests (INFO, SAMPLE, SAMPLE_DIR, FETCH_OPEN, COMPRESS
 * source): st_registry_get, and in a cluster sts_cluster_serves (ST_ENOTFOUND with a message
 * when the copy is not served). */
int  sts_get_served(sts_server *srv, const char *name, st_setref **ref, st_error *e);
/* CLUSTER: the membership as this node sees it (PROTOCOL.md 4.11); UNSUPPORTED without
 * --cluster. */
STS_HANDLER(sts_h_cluster);
/* The reply for a set this node does not hold: MOVED with a node's address when the cluster
 * knows where it is (docs/cluster.md), UNAVAILABLE when the catalogue records it but no live
 * node holds a copy, else NOT_FOUND with msg. Works without a cluster. */
void sts_reply_not_here(sts_server *srv, stp_buf *out, const stp_header *h, const char *name,
                        const char *msg);
/* A REPLICA_PUBLISH named other contents than this node's copy while etcd could not be
 * asked (h_upload.c): a repair pass is run as soon as etcd answers again (now, if it already
 * does), so the catalogue, not the message, decides whether the copy is stale. */
void sts_cluster_recheck(sts_cluster *cl);
/* Sleeps up to ms, or until a kick or stop; 1 when stopping (the repair thread). */
int  sts_cluster_nap(sts_cluster *cl, int ms);
/* Wakes the repair thread for a pass now. */
void sts_cluster_kick(sts_cluster *cl);
/* The repair thread, after each pass: whether this node's --advertise address reaches this
 * node (a CLUSTER there names this node's id); checked each pass until it does, then once a
 * minute; a change is logged (WARN while it does not), never fatal (docs/cluster.md). */
void sts_cluster_advertise_check(sts_cluster *cl);
/* STATS keys; returns how many were written (at most cap). */
size_t sts_cluster_stats(sts_cluster *cl, stp_stat *s, size_t cap);
/* Ranks the members for name: owners first. order[] gets up to k member indices. */
size_t sts_cluster_rank(const sts_cl_member *m, size_t n, const char *name, size_t *order, size_t k);

/* ---- cluster_repair.c ---- */
void *sts_cluster_repair_main(void *arg);

/* ---- cluster_write.c ---- */
typedef struct sts_cl_claim {
    char       name[STP_MAX_NAME + 1];
    scl_setrec rec;                   /* what was claimed */
    int64_t    mod_rev;               /* the claim's revision */
    int        had_prev;              /* a REPLACE: prev is what to put back */
    scl_setrec prev;
    int        repeat;                /* the same content was recorded already ("ok") */
} sts_cl_claim;
/* Step 2 of the write path. Returns a wire status (0, EXISTS, UNAVAILABLE, ...), msg set. */
int sts_cluster_claim(sts_cluster *cl, const char *name, uint32_t crc32c, uint32_t crc32,
                      uint64_t size, const char *fmt, const char *options, int replace,
                      sts_cl_claim *c, char *msg, size_t cap);
/* Takes a claim back (staging failed or the quorum was not reached). */
void sts_cluster_unclaim(sts_cluster *cl, const sts_cl_claim *c);
/* Steps 4-5: pushes this node's copy to the other owners, then finalizes. kind: the set's
 * kind; stage: the staged copy of an upload (datadir.h), NULL for the published copy (a
 * COMPRESS result). This node's own copy counts towards W (the staged one is durable). Returns
 * 0 or a wire status (UNAVAILABLE short of the quorum), msg set. */
int sts_cluster_replicate(sts_cluster *cl, sts_cl_claim *c, int kind, const char *stage,
                          char *msg, size_t cap);
/* DELETE in a cluster: records the delete, removes the local copy (through the caller's
 * function), forwards to the other holders. Returns a wire status. */
int sts_cluster_delete(sts_cluster *cl, const char *name,
                       int (*local_delete)(sts_server *srv, const char *name), char *msg,
                       size_t cap);
/* A COMPRESS result written to path (a data dir temp file, bytes long, format fmt; set: the
 * result, ownership passes): claimed, staged, pushed to the owners and finalized as an upload
 * is, then published here; a refused write drops its staged copy and leaves this node's copy
 * of the name as it was. path is gone afterwards. Returns a wire status, msg set. */
int sts_cluster_record_file(sts_cluster *cl, const char *name, int replace, int kind,
                            const char *path, const char *fmt, uint64_t bytes, st_set *set,
                            char *msg, size_t cap);
/* ---- cluster_fence.c ---- */
enum { STS_DOUBT_CLAIM, STS_DOUBT_FINALIZE, STS_DOUBT_UNCLAIM, STS_DOUBT_DELETE,
       STS_DOUBT_RESTORE };
typedef struct sts_cl_doubt {           /* a write and what undoing or redoing it needs */
    int          kind;                  /* STS_DOUBT_* */
    char         name[STP_MAX_NAME + 1];
    char         tag[1024];             /* the op key's value the write put */
    sts_cl_claim claim;                 /* CLAIM, FINALIZE, UNCLAIM */
    int          nacked;                /* FINALIZE: the copies/ keys it put */
    char         acked[STS_CL_MAX_HOLDERS + 1][STP_MAX_NODE_ID + 1];
    char        *rec;                   /* DELETE, RESTORE: the record's value as it was */
    scl_kvs      copies;                /* DELETE, RESTORE: its copies/ keys as they were */
    int          applied;               /* the fence showed it applied (undo without one) */
    int64_t      applied_rev;           /* then: the write's revision (the op key's) */
} sts_cl_doubt;
/* One transaction of the write path; the caller holds etcd_mu. The op key's compare
 * (mod_revision == op_rev) and put are added to cmp and ops; a write left in doubt is resolved
 * first (when that fails, so does this call, with nothing sent). On an etcd error the write is
 * in doubt: a copy of *d (rec and copies copied too) is kept until sts_cluster_resolve settles
 * it. *ok 0 means a compare of the caller failed. Returns an SCL_* code. */
int  sts_cluster_wtxn(sts_cluster *cl, scl_etcd *h, const scl_cmp *cmp, size_t ncmp,
                      const scl_op *ops, size_t nops, int *ok, int64_t *rev,
                      const sts_cl_doubt *d);
/* Settles the write in doubt, if any (caller holds etcd_mu): fences the op key, learns
 * whether the write was applied and undoes or completes it so that the cluster matches the
 * UNAVAILABLE the request was answered with. SCL_OK when nothing is in doubt any more. */
int  sts_cluster_resolve(sts_cluster *cl, scl_etcd *h);
/* Takes a claim back (caller holds etcd_mu): compare the record's mod_revision with rev, then
 * delete it (or put back the record it replaced) and the copies/ keys of acked. SCL_* code;
 * the outcome is logged. */
int  sts_cluster_take_back(sts_cluster *cl, scl_etcd *h, const sts_cl_claim *c, int64_t rev,
                           int nacked, const char (*acked)[STP_MAX_NODE_ID + 1]);
/* Makes d (NULL: none) the write in doubt, freeing the one before; with keep, d is first
 * written to the data dir (cluster_doubt_file.c) or the file removed. Caller holds etcd_mu. */
void sts_cluster_doubt_set(sts_cluster *cl, sts_cl_doubt *d, int keep);
/* 1 when name is the set of a write in doubt (repair keeps its local copy). */
int  sts_cluster_doubts(sts_cluster *cl, const char *name);
void sts_cluster_doubt_free(sts_cluster *cl);
/* Frees d, its record and copies/ keys (NULL is fine). */
void sts_cluster_doubt_free_one(sts_cl_doubt *d);

/* ---- cluster_doubt_file.c ---- */
/* Writes d to <data-dir>/cluster-doubt whole (NULL: removes the file); 0, or -1 (logged).
 * Caller holds etcd_mu. */
int  sts_cluster_doubt_save(sts_cluster *cl, const sts_cl_doubt *d);
/* At init: a write this node left in doubt in an earlier process becomes cl->doubt, with the
 * op key's revision it compared; a file of another node id or prefix, or unreadable, is
 * logged and removed. */
void sts_cluster_doubt_load(sts_cluster *cl);

/* Pushes the local copy of name to the node at addr (the repair thread): 0, or non-zero
 * with msg set; a failure is counted, not logged (the repair thread logs it once per
 * backoff). */
int sts_cluster_push(sts_cluster *cl, const char *name, const char *addr, char *msg, size_t cap);

/* Records this node's copy of name (set kind) in a catalogue that has lost it: the record
 * (state ok, version 1, this node as origin) and this node's copies/ key, only while the name
 * is free (cluster_write.c). 0 when etcd answered (recorded, or taken meanwhile), -1 else. */
int sts_cluster_rerecord(sts_cluster *cl, const char *name, int kind);

/* The catalogue's identity (cluster_mark.c, docs/cluster.md "Catalogue lost"): checks the
 * PREFIX/cluster key at revision rev against the one kept in <data-dir>/cluster-id, and the
 * revision watch. 0: the catalogue this node knows (or the first it joins: the id is kept
 * now); 1: not the one its data dir knows (etcd lost its data, or a prefix found without a
 * mark, or etcd went back to a revision below one this node has seen: restored from an older
 * snapshot or backup, its mark with it): the pass must
 * drop nothing, record its sets again (sts_cluster_rerecord) and then call
 * sts_cluster_mark_adopt; < 0: an etcd error. */
int sts_cluster_mark_check(sts_cluster *cl, int64_t rev);
/* Keeps the mark the last check saw in the data dir with the revision of the catalogue that
 * check read (after every local set was recorded again), and makes that revision the watch's
 * highest; 0 or -1. */
int sts_cluster_mark_adopt(sts_cluster *cl);
/* At init, before any etcd call: the revision the cluster-id file keeps seeds the watch. */
void sts_cluster_mark_load(sts_cluster *cl);
/* Called by an ordinary pass before it drops a local or staged copy (rec_rev 0), and for each
 * local copy it confirms current (rec_rev: its record's mod_revision): keeps the highest
 * revision seen (as of the pass's check) in the cluster-id file when it is above the kept one
 * and something is at stake (a drop, or a record newer than the kept revision); the check
 * also keeps it every 10th ordinary pass while it moves. docs/cluster.md "Catalogue lost"; at most one
 * write a pass. */
void sts_cluster_rev_keep(sts_cluster *cl, int64_t rec_rev);
/* At start: puts PREFIX/config with this node's replicas and write quorum when there is none;
 * -1 (logged) when it holds others; 0 also when etcd does not answer (not checked, logged). */
int sts_cluster_settings_check(sts_cluster *cl);
/* 64 random bits, never 0 (incarnations, the catalogue's mark). */
uint64_t sts_cluster_random_id(void);

#endif
