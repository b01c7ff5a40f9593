/* server/handles.c - one small table of handles (handles.h): ids, lookup by id and owner,
 * live count against a capacity, unlinking by predicate.
 *
 * Owns: the list and its counters. Does not own: the records (uploads.c, h_jobs.c allocate
 * and free them) or their rules (expiry, states). The lists are short (bounded by max-uploads,
 * max-jobs + 256 finished jobs, 256 fetches), so a linked list searched linearly is enough.
 */
#include <stddef.h>

#include "handles.h"

void sts_handles_init(sts_handles *t)
{
    pthread_mutex_init(&t->mu, NULL);
    t->list = NULL;
    t->live = 0;
    t->next_id = 0;
}

void sts_handles_destroy(sts_handles *t)
{
    pthread_mutex_destroy(&t->mu);
}

void sts_handles_lock(sts_handles *t)
{
    pthread_mutex_lock(&t->mu);
}

void sts_handles_unlock(sts_handles *t)
{
    pthread_mutex_unlock(&t->mu);
}

int sts_handles_add_locked(sts_handles *t, sts_handle *h, uint64_t cap)
{
    if (t->live >= cap)
        return -1;
    h->id = ++t->next_id;
    h->live = 1;
    h->next = t->list;
    t->list = h;
    t->live++;
    return 0;
}

sts_handle *sts_handles_find_locked(sts_handles *t, uint64_t id, uint64_t owner)
{
    for (sts_handle *h = t->list; h; h = h->next)
        if (h->id == id)
            return owner == STS_ANY_OWNER || h->owner == owner ? h : NULL;
    return NULL;
}

void sts_handles_retire_locked(sts_handles *t, sts_handle *h)
{
    if (h->live) {
        h->live = 0;
        t->live--;
    }
}

void sts_handles_unlink_locked(sts_handles *t, sts_handle *h)
{
    for (sts_handle **pp = &t->list; *pp; pp = &(*pp)->next)
        if (*pp == h) {
            *pp = h->next;
            h->next = NULL;
            sts_handles_retire_locked(t, h);
            return;
        }
}

sts_handle *sts_handles_unlink_if(sts_handles *t, int (*pick)(sts_handle *h, void *arg),
                                  void *arg)
{
    sts_handle *taken = NULL, **tail = &taken;
    pthread_mutex_lock(&t->mu);
    for (sts_handle **pp = &t->list; *pp;) {
        sts_handle *h = *pp;
        if (pick(h, arg)) {
            *pp = h->next;
            sts_handles_retire_locked(t, h);
            h->next = NULL;
            *tail = h;    /* keeps list order: newest first */
            tail = &h->next;
        } else {
            pp = &h->next;
        }
    }
    pthread_mutex_unlock(&t->mu);
    return taken;
}
