/* util/bigalloc.c - large buffers on transparent huge pages (see bigalloc.h). */
#include "bigalloc.h"

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

#define HUGE_PAGE ((size_t)2 << 20)
#define TEMP_HUGE_FROM ((size_t)256 << 10)

void *stu_big_alloc(size_t n, int use)
{
    if (n > SIZE_MAX / 2) {
        errno = ENOMEM;
        return NULL;
    }
    size_t r = n ? (n + 63) & ~(size_t)63 : 64, up = (n + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
    size_t huge = 0; /* bytes from the start marked for huge pages */
    if (use == STU_BIG_TEMP ? n >= TEMP_HUGE_FROM : n && up - n <= n / 2)
        r = huge = up;
    else if (use == STU_BIG_KEEP)
        huge = n & ~(HUGE_PAGE - 1);
    /* a small temporary buffer from malloc: glibc serves it from its heap, where freeing it
     * is not an munmap (which cost about as much as reading a 130 KiB file) */
    void *p = NULL;
    if (!huge && use == STU_BIG_TEMP)
        p = malloc(r);
    else if (posix_memalign(&p, huge ? HUGE_PAGE : 64, r) != 0)
        p = NULL;   /* not aligned_alloc: C11 wants its size a multiple of the alignment,
                       and a KEEP buffer with a 4 KiB-page tail is not one */
    if (!p) {
        errno = ENOMEM;
        return NULL;
    }
#ifdef MADV_HUGEPAGE
    if (huge)
        madvise(p, huge, MADV_HUGEPAGE); /* advice only: failure changes nothing */
#endif
    return p;
}
