/* tests/common/etcd_hold.h - a loopback proxy in front of a test etcd that can hold its
 * transactions: the way to make "etcd applied a write after the node gave up on it" happen
 * on purpose (a paused etcd does it only sometimes: it may or may not still run a request
 * whose client has gone when it continues); and that can cut its node off etcd while the
 * other nodes still reach it.
 *
 * Owns: a listening socket on a free loopback port, one thread accepting and one thread per
 * connection relaying bytes to etcd's client port. While holding, a request `POST
 * /v3/kv/txn` is kept (never forwarded, never answered: its client times out); every other
 * request goes through (muting: a transaction is forwarded but its answer dropped; cut: every
 * connection is closed). A replay sends the kept requests to etcd in the order they came,
 * each on its own connection, and waits until etcd answers each (then it has applied it),
 * whether or not its client is still there. Does not own: etcd (etcd_fixture.h).
 */
#ifndef ST_ETCD_HOLD_H
#define ST_ETCD_HOLD_H

#include <stddef.h>

typedef struct st_etcd_hold st_etcd_hold;

/* Starts a proxy for the etcd at 127.0.0.1:etcd_port; url gets
 * "etcd://127.0.0.1:<proxy port><prefix>" (cap bytes). NULL on failure (reason on stderr). */
st_etcd_hold *st_etcd_hold_start(int etcd_port, const char *prefix, char *url, size_t cap);
/* Starts holding transactions; the next `pass` of them still go through. */
void st_etcd_hold_on(st_etcd_hold *p, int pass);
/* Starts muting transactions (the next `pass` of them still go through as usual): they are
 * sent to etcd at once, which applies them, but their answers (and whatever else comes back
 * on that connection) never reach the client, which times out: a reply lost after the
 * write. */
void st_etcd_hold_mute(st_etcd_hold *p, int pass);
/* Cuts the node off (on = 1) or lets it through again (0): while cut, every connection to
 * the proxy is closed, those open and new ones, before anything reaches etcd: an etcd the
 * node cannot reach at all (its calls fail at once). */
void st_etcd_hold_cut(st_etcd_hold *p, int on);
/* Stops holding and muting: transactions go through again; the kept ones stay kept. */
void st_etcd_hold_off(st_etcd_hold *p);
/* Sends the kept (complete) transactions to etcd; returns how many etcd answered. */
int  st_etcd_hold_replay(st_etcd_hold *p);
/* How many complete transactions are kept now. */
int  st_etcd_hold_count(st_etcd_hold *p);
/* Closes every connection and frees p (kept transactions are dropped). NULL is fine. */
void st_etcd_hold_stop(st_etcd_hold *p);

#endif
