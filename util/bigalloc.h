/* util/bigalloc.h - allocation of large buffers that are written right after they are
 * allocated (a set's texel arena, a whole file read into memory), libc only.
 *
 * Why: every 4 KiB page touched for the first time costs a page fault, and on a virtual
 * machine with shadow or nested paging far more (measured on the project's machines: writing
 * 4 MiB of fresh 4 KiB pages took 13-27 ms of CPU, of fresh 2 MiB transparent huge pages
 * 0.5-0.8 ms). A buffer of at least huge_from bytes is therefore 2 MiB aligned, rounded up to
 * whole 2 MiB pages and marked MADV_HUGEPAGE (advice: without transparent huge pages it is
 * an ordinary buffer). The rounding is the caller's trade: up to 2 MiB - 1 of unused memory
 * per buffer, so a long-lived buffer asks from a larger size than a short-lived one.
 *
 * Ownership: the caller frees the buffer with free(). Smaller buffers are 64-byte aligned.
 * *cap (when not NULL) receives the usable size, at least n. NULL with errno ENOMEM when the
 * memory cannot be had (n of 0 gives a 64-byte buffer).
 */
#ifndef STU_BIGALLOC_H
#define STU_BIGALLOC_H

#include <stddef.h>

#define STU_HUGE_PAGE ((size_t)2 << 20)

void *stu_big_alloc(size_t n, size_t huge_from, size_t *cap);

#endif
