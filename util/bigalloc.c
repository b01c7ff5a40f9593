/* util/bigalloc.c - large buffers on transparent huge pages (see bigalloc.h). */
#include "bigalloc.h"
#include "loadpath.h"

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

#define HUGE_PAGE ((size_t)2 << 20)
#define PAGE ((uintptr_t)4096)
#define POPULATE_FROM ((size_t)16 << 10) /* below: at most 4 faults, about one madvise */
#define TEMP_HUGE_FROM ((size_t)256 << 10)
#define KEEP_HUGE_FROM (HUGE_PAGE / 3) /* 2/3 MiB: the rounding adds at most twice n */

/* The bytes to allocate for n: a multiple of 64, or of the huge page when the buffer goes on
 * huge pages (*huge 1). n <= SIZE_MAX / 2. */
static size_t plan(size_t n, int use, int *huge)
{
    *huge = n >= (use == STU_BIG_TEMP ? TEMP_HUGE_FROM : KEEP_HUGE_FROM);
    if (*huge)
        return (n + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
    return n ? (n + 63) & ~(size_t)63 : 64;
}

STU_LOADPATH
size_t stu_big_footprint(size_t n, int use)
{
    int huge;
    return n > SIZE_MAX / 2 ? n : plan(n, use, &huge);
}

STU_LOADPATH
void *stu_big_alloc(size_t n, int use)
{
    if (n > SIZE_MAX / 2) {
        errno = ENOMEM;
        return NULL;
    }
    int huge;
    size_t r = plan(n, use, &huge);
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
        madvise(p, r, MADV_HUGEPAGE); /* advice only: failure changes nothing */
#endif
#ifdef MADV_POPULATE_WRITE
    /* the n bytes the caller is about to write, faulted in by one call (not the rounding past
     * them: without huge pages it would stay untouched); the whole pages around them belong
     * to the same mapping (malloc's heap or this buffer's own mmap). Fails harmlessly
     * (EINVAL) before Linux 5.14, and leaves the pages to be faulted one by one. */
    if (n >= POPULATE_FROM) {
        uintptr_t a = (uintptr_t)p & ~(PAGE - 1), z = ((uintptr_t)p + n + PAGE - 1) & ~(PAGE - 1);
        madvise((void *)a, z - a, MADV_POPULATE_WRITE);
    }
#endif
    return p;
}
