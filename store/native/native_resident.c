/* store/native/native_resident.c - how much of a mapped set is resident, and its release
 * (the memory budget's measure, server/budget.c; the two counts are described in native.h).
 *
 * Owns: st_native_meter_*, st_native_resident, st_native_release. Does not own: when to
 * measure or release (the budget), the mapping itself (native_read.c maps, st_set_free unmaps).
 *
 * /proc/self/pagemap holds one 64-bit entry per virtual page of this process, at byte offset
 * (address / page size) * 8; bit 63 is set while the page is present in the page tables. It is
 * readable by the process itself without privilege (the frame numbers it also holds are zeroed
 * then; only bit 63 is used). Measured on this project's VM (kernel 6.18, 256 MB file): reading
 * it costs ~15 ns a page against ~1 ns for mincore; a fault back from the page cache ~1.7 us a
 * page, from the disk ~430 us a page (docs/native.md "Measured").
 */
#include "native.h"

#include <fcntl.h>
#include <stdint.h>
#include <sys/mman.h>
#include <unistd.h>

st_native_count st_native_meter_open(st_native_meter *m)
{
    m->pagemap_fd = open("/proc/self/pagemap", O_RDONLY | O_CLOEXEC);
    return st_native_meter_count(m);
}

void st_native_meter_close(st_native_meter *m)
{
    if (m && m->pagemap_fd >= 0)
        close(m->pagemap_fd);
    if (m)
        m->pagemap_fd = -1;
}

st_native_count st_native_meter_count(const st_native_meter *m)
{
    return m && m->pagemap_fd >= 0 ? ST_NATIVE_COUNT_MAPPED : ST_NATIVE_COUNT_CACHED;
}

/* Pages [first, first + n) of the mapping in the page cache (mincore). */
static size_t cached_pages(const uint8_t *map, size_t pg, size_t first, size_t n)
{
    unsigned char vec[4096];
    size_t res = 0;
    for (size_t i = 0; i < n; i += sizeof vec) {
        size_t k = n - i < sizeof vec ? n - i : sizeof vec;
        if (mincore((void *)(map + (first + i) * pg), k * pg, vec) != 0)
            return res;
        for (size_t j = 0; j < k; j++)
            res += vec[j] & 1;
    }
    return res;
}

/* Pages [first, first + n) of the mapping present in this process's page tables (pagemap). */
static size_t mapped_pages(int fd, const uint8_t *map, size_t pg, size_t first, size_t n)
{
    uint64_t ent[512];
    size_t res = 0, vpn0 = (size_t)((uintptr_t)map / pg) + first;
    for (size_t i = 0; i < n; i += 512) {
        size_t k = n - i < 512 ? n - i : 512;
        ssize_t got = pread(fd, ent, k * sizeof ent[0], (off_t)((vpn0 + i) * sizeof ent[0]));
        if (got != (ssize_t)(k * sizeof ent[0]))
            return res + cached_pages(map, pg, first + i, n - i);
        for (size_t j = 0; j < k; j++)
            res += (size_t)(ent[j] >> 63);
    }
    return res;
}

size_t st_native_resident(const st_set *s, const st_native_meter *m)
{
    if (!s || !s->map)
        return 0;
    size_t pg = (size_t)sysconf(_SC_PAGESIZE), npages = (s->map_len + pg - 1) / pg;
    const uint8_t *map = s->map;
    size_t n = st_native_meter_count(m) == ST_NATIVE_COUNT_MAPPED
                   ? mapped_pages(m->pagemap_fd, map, pg, 0, npages)
                   : cached_pages(map, pg, 0, npages);
    return n * pg;
}

size_t st_native_release(const st_set *s, const st_native_meter *m)
{
    if (!s || !s->map)
        return 0;
    size_t was = st_native_resident(s, m);
    if (st_native_meter_count(m) == ST_NATIVE_COUNT_MAPPED) {
        madvise(s->map, s->map_len, MADV_COLD);   /* first: it acts on mapped pages only */
        madvise(s->map, s->map_len, MADV_DONTNEED);
    } else {
        madvise(s->map, s->map_len, MADV_DONTNEED);
        posix_fadvise(s->map_fd, 0, (off_t)s->map_len, POSIX_FADV_DONTNEED);
    }
    return was;
}
