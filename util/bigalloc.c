/* util/bigalloc.c - large buffers on transparent huge pages (see bigalloc.h). */
#include "bigalloc.h"

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

void *stu_big_alloc(size_t n, size_t huge_from, size_t *cap)
{
    size_t r;
    void *p;
    if (n >= huge_from && n <= SIZE_MAX - STU_HUGE_PAGE) {
        r = (n + STU_HUGE_PAGE - 1) & ~(STU_HUGE_PAGE - 1);
        p = aligned_alloc(STU_HUGE_PAGE, r);
#ifdef MADV_HUGEPAGE
        if (p)
            madvise(p, r, MADV_HUGEPAGE); /* advice only: failure changes nothing */
#endif
    } else {
        if (n > SIZE_MAX - 63) {
            errno = ENOMEM;
            return NULL;
        }
        r = n ? (n + 63) & ~(size_t)63 : 64;
        p = aligned_alloc(64, r);
    }
    if (!p) {
        errno = ENOMEM;
        return NULL;
    }
    if (cap)
        *cap = r;
    return p;
}
