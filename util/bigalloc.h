/* util/bigalloc.h - allocation of large buffers that are written right after they are
 * allocated (a set's texel arena, a whole file read into memory), libc only.
 *
 * Why: every 4 KiB page touched for the first time costs a page fault, and on a virtual
 * machine with shadow or nested paging far more. Measured on the project's 2-core VM
 * (2026-12-02, load 10-15): writing 4 MiB of fresh 4 KiB pages took 13-27 ms of CPU, of
 * fresh 2 MiB transparent huge pages 0.5-0.8 ms; reading a 2 MiB file into a fresh buffer
 * 13-24 ms, into a huge-page buffer 1-1.9 ms. So large buffers are 2 MiB aligned and marked
 * MADV_HUGEPAGE (advice only: without transparent huge pages they are ordinary buffers).
 *
 * Measured again (2026-12-02 04:50-05:00, load 10-14): a fresh 4 KiB page cost 20-25 us
 * (1 MiB of them 5-7 ms), one fresh 2 MiB huge page 0.3-0.5 ms with its zeroing; so a huge
 * page is cheaper in CPU from about 64-100 KiB of 4 KiB pages on.
 *
 * A huge page is allocated whole, so rounding a buffer up to whole huge pages costs memory:
 * - STU_BIG_KEEP (a buffer that lives long, like a set's arena): rounded up to whole huge
 *   pages from 2/3 MiB on (the rounding adds at most twice n, and less than 2 MiB); a set
 *   of 0.7-1.3 MiB was the import's slowest case: 170-330 fresh 4 KiB pages, 4-7 ms of
 *   faults, more than its decoding (before: from 4/3 MiB on).
 * - STU_BIG_TEMP (a buffer freed soon, like a file being parsed): rounded up from 256 KiB on.
 * stu_big_footprint says how many bytes a buffer of n really holds (for memory accounting).
 *
 * Pre-faulting (2026-12-03): a buffer of 16 KiB or more has its n bytes (not the rounding
 * past them) faulted in right away by one madvise(MADV_POPULATE_WRITE) (Linux 5.14 on; an
 * older kernel refuses it and the pages fault one by one as before). Every caller writes all
 * n bytes at once (an importer its whole arena, a file read its buffer), so this makes
 * nothing resident that would not be. Measured (load 5, fresh 4 KiB pages): 256 KiB written
 * page by page 0.77 ms of CPU, populated first 0.41 ms; one 2 MiB huge page 0.13-0.22 ms.
 * Smaller buffers are 64-byte aligned, sized up to a multiple of 64. Aligned buffers come from
 * posix_memalign (aligned_alloc wants a size that is a multiple of the alignment).
 *
 * Ownership: the caller frees the buffer with free(). NULL with errno ENOMEM when the memory
 * cannot be had (n of 0 gives a 64-byte buffer).
 */
#ifndef STU_BIGALLOC_H
#define STU_BIGALLOC_H

#include <stddef.h>

enum { STU_BIG_KEEP = 0, STU_BIG_TEMP = 1 };

void *stu_big_alloc(size_t n, int use);

/* Bytes that stu_big_alloc(n, use) reserves: n rounded up to 64 bytes, or to whole huge
 * pages when it is put on them (an upper bound of what becomes resident). */
size_t stu_big_footprint(size_t n, int use);

#endif
