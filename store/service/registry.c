/* store/service/registry.c - the named-set registry (see registry.h).
 *
 * Owns: a sorted array of references, one per name, under one mutex; reference counting with
 * atomic builtins. Does not own: files, sockets. Expected load: tens to thousands of names,
 * lookups on every SAMPLE request (binary search, a few hundred ns), rare puts and removes.
 */
#include "registry.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct st_registry {
    pthread_mutex_t mu;
    st_setref     **items;   /* sorted by name */
    size_t          n, cap;
    uint64_t        next_gen;
};

int st_name_check(const char *name, size_t len, st_error *e)
{
    size_t at = 0;
    int problem = stp_name_check(name, len, &at);
    if (problem == STP_NAME_OK)
        return 0;
    if (problem == STP_NAME_TOO_LONG)
        return st_fail(e, ST_EINVAL, "set name is %zu bytes, the limit is %d", len, ST_NAME_MAX);
    if (problem == STP_NAME_BAD_BYTE)
        return st_fail(e, ST_EINVAL, "set name has byte 0x%02x at offset %zu; allowed: A-Z a-z "
                       "0-9 . _ -", (unsigned char)name[at], at);
    return st_fail(e, ST_EINVAL, "%s", stp_name_problem_text(problem));
}

st_registry *st_registry_create(void)
{
    st_registry *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    pthread_mutex_init(&r->mu, NULL);
    r->next_gen = 1;
    return r;
}

void st_setref_retain(st_setref *ref)
{
    __atomic_add_fetch(&ref->refs_, 1, __ATOMIC_RELAXED);
}

void st_setref_release(st_setref *ref)
{
    if (!ref)
        return;
    if (__atomic_sub_fetch(&ref->refs_, 1, __ATOMIC_ACQ_REL) == 0) {
        st_set_free(ref->set);
        free(ref);
    }
}

void st_registry_free(st_registry *r)
{
    if (!r)
        return;
    for (size_t i = 0; i < r->n; i++)
        st_setref_release(r->items[i]);
    free(r->items);
    pthread_mutex_destroy(&r->mu);
    free(r);
}

/* Index of name, or -(insertion point) - 1. Caller holds the mutex. */
static long find(const st_registry *r, const char *name)
{
    size_t lo = 0, hi = r->n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        int c = strcmp(r->items[mid]->name, name);
        if (c == 0)
            return (long)mid;
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return -(long)lo - 1;
}

int st_registry_put(st_registry *r, const char *name, st_set *set, const st_set_source *src,
                    size_t max_sets, int *replaced, st_error *e)
{
    if (replaced)
        *replaced = 0;
    int rc = st_name_check(name, name ? strlen(name) : 0, e);
    if (rc) {
        st_set_free(set);
        return rc;
    }
    if (!set)
        return st_fail(e, ST_EINVAL, "no set to publish");
    st_setref *ref = calloc(1, sizeof *ref);
    if (!ref) {
        st_set_free(set);
        return st_fail(e, ST_ENOMEM, "registry entry");
    }
    ref->set = set;
    memcpy(ref->name, name, strlen(name) + 1);
    ref->refs_ = 1;
    if (src) {
        ref->source_bytes = src->bytes;
        ref->source_crc = src->crc;
        if (src->format) {
            strncpy(ref->format, src->format, sizeof ref->format - 1);
        }
    }
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ref->created_ms = (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;

    st_setref *old = NULL;
    pthread_mutex_lock(&r->mu);
    ref->gen = r->next_gen++;
    long i = find(r, name);
    if (i >= 0) {
        old = r->items[i];
        r->items[i] = ref;
    } else {
        if (max_sets && r->n >= max_sets) {
            pthread_mutex_unlock(&r->mu);
            st_setref_release(ref);
            return st_fail(e, ST_EBUSY, "the registry holds %zu sets, the limit", r->n);
        }
        if (r->n == r->cap) {
            size_t ncap = r->cap ? r->cap * 2 : 16;
            st_setref **ni = realloc(r->items, ncap * sizeof *ni);
            if (!ni) {
                pthread_mutex_unlock(&r->mu);
                st_setref_release(ref);
                return st_fail(e, ST_ENOMEM, "registry table");
            }
            r->items = ni;
            r->cap = ncap;
        }
        size_t at = (size_t)(-i - 1);
        memmove(r->items + at + 1, r->items + at, (r->n - at) * sizeof *r->items);
        r->items[at] = ref;
        r->n++;
    }
    pthread_mutex_unlock(&r->mu);
    if (old) {
        if (replaced)
            *replaced = 1;
        st_setref_release(old);  /* outside the lock: may free a large set */
    }
    return 0;
}

int st_registry_get(st_registry *r, const char *name, st_setref **out, st_error *e)
{
    *out = NULL;
    pthread_mutex_lock(&r->mu);
    long i = find(r, name);
    if (i >= 0) {
        *out = r->items[i];
        st_setref_retain(*out);
    }
    pthread_mutex_unlock(&r->mu);
    if (!*out)
        return st_fail(e, ST_ENOTFOUND, "no set named '%.200s'", name);
    return 0;
}

int st_registry_remove(st_registry *r, const char *name, st_error *e)
{
    st_setref *old = NULL;
    pthread_mutex_lock(&r->mu);
    long i = find(r, name);
    if (i >= 0) {
        old = r->items[i];
        memmove(r->items + i, r->items + i + 1, (r->n - (size_t)i - 1) * sizeof *r->items);
        r->n--;
    }
    pthread_mutex_unlock(&r->mu);
    if (!old)
        return st_fail(e, ST_ENOTFOUND, "no set named '%.200s'", name);
    st_setref_release(old);
    return 0;
}

uint64_t st_registry_next_gen(st_registry *r)
{
    pthread_mutex_lock(&r->mu);
    uint64_t g = r->next_gen;
    pthread_mutex_unlock(&r->mu);
    return g;
}

size_t st_registry_count(st_registry *r)
{
    pthread_mutex_lock(&r->mu);
    size_t n = r->n;
    pthread_mutex_unlock(&r->mu);
    return n;
}

size_t st_registry_snapshot(st_registry *r, st_setref **out, size_t max)
{
    pthread_mutex_lock(&r->mu);
    size_t n = r->n < max ? r->n : max;
    for (size_t i = 0; i < n; i++) {
        out[i] = r->items[i];
        st_setref_retain(out[i]);
    }
    pthread_mutex_unlock(&r->mu);
    return n;
}

uint64_t st_registry_memory(st_registry *r)
{
    uint64_t sum = 0;
    pthread_mutex_lock(&r->mu);
    for (size_t i = 0; i < r->n; i++)
        sum += st_set_memory(r->items[i]->set);
    pthread_mutex_unlock(&r->mu);
    return sum;
}
