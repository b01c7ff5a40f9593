/* store/ptex/ptex_inflate.h - a small zlib-stream inflater for the Ptex reader's small blocks.
 *
 * Why: a Ptex file of small faces is hundreds of zlib streams of a few hundred bytes, and a
 * small file is a handful of them. libdeflate (which the reader keeps for the larger streams
 * of larger files: ptex_read.c's inflate_exact says which) sets up decode tables of 2^11
 * entries per stream and its decompressor is an 11 KB allocation zeroed on creation: in a
 * fresh process 3 fresh heap pages, its code pages and its symbol bindings, more than a small
 * file's whole import. This one decodes the fixed code by code range with no table, a dynamic
 * code with a root table sized to the code (at most 2^9 entries, on the stack, built by
 * doubling) and a canonical decoder for longer codes, and computes the Adler-32 itself (SSE2,
 * AVX2 when the CPU has it), so a small stream touches no heap and no other library. On the
 * small streams of small files it is the faster of the two (teapot's 448 level-0 streams,
 * warm: 0.93 ms against libdeflate's 1.19); on large streams libdeflate is faster per byte
 * (a 16 KiB stream of long matches: ~1.3x; tri's 12 KB nearly incompressible ones: ~1.1x).
 *
 * Owns: decoding one zlib stream (RFC 1950 / 1951) of stored, fixed and dynamic blocks into a
 * caller buffer of known size. The 2-byte zlib header is the caller's (ptex_read.c checks
 * it); in points at it. Does the same checks as zlib and libdeflate: bad block type, stored
 * length mismatch, over-subscribed or incomplete codes (an incomplete literal/length or
 * distance code is allowed only as a single code of length 1, as zlib allows it), missing
 * end-of-block code, bad repeat, invalid symbols, a distance too far back, truncated input,
 * a missing or wrong Adler-32. Bytes after the Adler-32 are ignored (as libdeflate's
 * libdeflate_zlib_decompress does).
 * Threading: a pure function on caller memory; about 3 KB of stack for a dynamic-code block.
 *
 * Header-only (static functions), included by ptex_read.c alone (and its unit test): its code
 * then sits in the reader's object, next to the reader's code. A fresh process pays for every
 * 64 KiB window of code it first runs (a page fault of about 10 us on the project's VM), and
 * as a separate object the linker placed it megabytes away from the reader.
 *
 * Bits are read LSB first from a 64-bit buffer, refilled (to at least 56 bits) whenever fewer
 * are left than the next step can take: 15 for a code, 33 for a length's extra bits with
 * the distance code and its extra bits, 14 for a code-length code with its extra bits; a
 * dynamic block's literal loop refills at every step, without a branch while 8 input bytes
 * are left, and takes up to three root literals per step.
 * Past the end of the input the buffer is filled with zero bytes that are counted (`over`);
 * consuming any of them is a truncated stream, checked at every block end and before the
 * check value (a run on phantom zeros cannot loop: every symbol writes output, ends a block,
 * or fails, and the output is bounded). The fixed code is decoded without tables (by code
 * ranges); a dynamic block's tables are on its own frame, so a stream of stored and fixed
 * blocks keeps a small stack. Copies and fills are loops of our own (GCC 12 -O2 emits no
 * library call in pi_codes, pi_build, pi_dynamic; only a stored block's copy is memcpy):
 * a first call into libc from deep in a dynamic block's frame would bind the symbol there,
 * and the binding's saved register state reached a fresh stack page.
 *
 * A Huffman code is decoded by a root table indexed by the next rbits bits (rbits = the
 * code's longest length, capped at 9 for literals / lengths, 8 for distances, 7 for the
 * code-length code): entry = symbol << 6 | length (the low 6 bits are the shift count as
 * x86's shift takes it, so the literal chain - look up, shift - has no mask in it), 0 for a
 * code longer than the root, which is then decoded canonically from the root's length + 1
 * on (pi_decode_long: the next 15 bits reversed, compared with each length's first code).
 * The root table grows by doubling (pi_build): one store per code and one copy of the table
 * in all, where filling each code's 2^(rbits - length) entries cost a store each. The code
 * lengths' counts come from the code-length decoder (a repeat adds its count at once) and
 * the symbols are sorted by length without a branch (unused ones go past the used ones).
 */
#ifndef ST_PTEX_INFLATE_H
#define ST_PTEX_INFLATE_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define PI_AVX2 1 /* an AVX2 Adler-32 when the CPU has it (target attribute, runtime check) */
#endif

#include "loadpath.h"

enum {
    ST_PTX_INFL_OK = 0,     /* *got bytes written (may be fewer than outlen: caller checks) */
    ST_PTX_INFL_BAD = 1,    /* malformed, truncated, or a wrong check value: *why says which */
    ST_PTX_INFL_OVER = 2,   /* the stream inflates to more than outlen bytes */
};

/* root table bits at most: literal/length, distance codes (small tables: a small stream
 * decodes a few hundred symbols, and the tables are on the stack) */
enum { PI_CODES, PI_LIT, PI_DIST, PI_LIT_RMAX = 9, PI_DIST_RMAX = 8 };


typedef struct pi_huff {
    uint16_t count[16];         /* codes of each length; count[0] unused symbols */
    uint16_t first[16];         /* the canonical code of each length's first symbol */
    uint16_t index[16];         /* sym[] position of each length's first symbol */
    uint16_t *sym;              /* symbols by (length, value): canonical order */
    uint16_t *root;             /* 1 << rbits entries: symbol << 6 | length (the low 6 bits
                                   a shift count as x86 takes it); 0: longer code */
    unsigned rbits, mask;       /* mask = (1 << rbits) - 1 */
    unsigned maxlen;            /* the longest code's length */
} pi_huff;

typedef struct pi_bits {
    const uint8_t *p, *end;
    uint64_t bb;                /* bits not yet consumed, LSB first; above bc: 0 or the next */
    unsigned bc;                /* valid bits in bb */
    size_t over;                /* zero bytes loaded past the end of the input */
} pi_bits;

static inline uint64_t pi_rd64le(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, 8);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    return v;
}

/* At least 56 bits in the buffer. */
static inline void pi_refill(pi_bits *s)
{
    if (s->end - s->p >= 8) {
        s->bb |= pi_rd64le(s->p) << s->bc;
        s->p += (63 - s->bc) >> 3;
        s->bc |= 56;
        return;
    }
    while (s->bc <= 56) {
        if (s->p < s->end)
            s->bb |= (uint64_t)*s->p++ << s->bc;
        else
            s->over++;
        s->bc += 8;
    }
}

static inline unsigned pi_take(pi_bits *s, unsigned n)
{
    unsigned v = (unsigned)(s->bb & (((uint64_t)1 << n) - 1));
    s->bb >>= n;
    s->bc -= n;
    return v;
}

/* Consumed any of the zero bytes past the input? */
static inline int pi_overran(const pi_bits *s)
{
    return s->over * 8 > s->bc;
}

/* Drops the bits up to the next byte boundary; the next input byte then. NULL when that is
 * past the end of the input. */
static const uint8_t *pi_align(pi_bits *s)
{
    pi_take(s, s->bc & 7);
    size_t inbuf = s->bc >> 3;           /* whole bytes in the buffer, phantoms included */
    if (s->over > inbuf)
        return NULL;
    return s->p - (inbuf - s->over);
}

/* Builds h from n code lengths (0..15); rmax caps the root table; cnt: the lengths' counts
 * when the caller has them (the code-length decoder counts runs), or NULL. 0, or -1 for an
 * over-subscribed or (as zlib) an incomplete code. h->sym has room for n symbols. */
STU_LOADPATH
static int pi_build(pi_huff *h, const uint8_t *lens, unsigned n, unsigned rmax, int kind,
                    const uint16_t *cnt)
{
    if (cnt) {
        memcpy(h->count, cnt, sizeof h->count);
    } else {
        memset(h->count, 0, sizeof h->count);
        for (unsigned i = 0; i < n; i++)
            h->count[lens[i]]++;
    }
    unsigned maxlen = 0;
    int left = 1;
    for (unsigned len = 1; len < 16; len++) {
        left <<= 1;
        left -= h->count[len];
        if (left < 0)
            return -1;
        if (h->count[len])
            maxlen = len;
    }
    if (maxlen && left > 0 && (kind == PI_CODES || maxlen != 1))
        return -1; /* incomplete: only a single code of length 1 may be (no code at all is
                      allowed too: any symbol decoded then fails) */
    uint16_t offs[16];
    h->first[1] = 0;
    h->index[1] = 0;
    offs[1] = 0;
    for (unsigned len = 1; len < 15; len++) {
        h->first[len + 1] = (uint16_t)((h->first[len] + h->count[len]) << 1);
        h->index[len + 1] = offs[len + 1] = (uint16_t)(h->index[len] + h->count[len]);
    }
    /* symbols of length 0 go past the coded ones (no branch on the length); eight unused
     * symbols in a row are skipped at once (a small stream's codes use few of the 286) */
    offs[0] = (uint16_t)(h->index[15] + h->count[15]);
    unsigned i = 0;
    for (; i + 8 <= n; i += 8) {
        uint64_t w;
        memcpy(&w, lens + i, 8);
        if (!w)
            continue;
        for (unsigned j = i; j < i + 8; j++)
            h->sym[offs[lens[j]]++] = (uint16_t)j;
    }
    for (; i < n; i++)
        h->sym[offs[lens[i]]++] = (uint16_t)i;
    unsigned rb = maxlen < rmax ? maxlen : rmax;
    h->rbits = rb;
    h->mask = (1u << rb) - 1;
    h->maxlen = maxlen;
    /* The root table grows by doubling: while its size is 2^len, entry j holds the code of
     * at most len bits whose bit-reversed value (the stream's bit order) is j mod 2^its
     * length, or 0. Doubling it (a copy of its lower half into its upper half) keeps that
     * true for the codes already in it; then each code of length len + 1 has exactly one
     * entry to write. So the table costs one store per code of up to rb bits and one copy
     * of 2^rb entries in all, instead of 2^(rb - len) stores per code. An entry left 0 is the
     * prefix of a longer code (decoded canonically: pi_decode) or no code at all (for the
     * two codes allowed incomplete). rc is the code's reversed value, incremented in
     * reversed order (a longer code extends it with zero bits: the same value). */
    uint16_t *t = h->root;
    t[0] = 0;
    t[1] = 0;
    unsigned rc = 0, k = 0;
    for (unsigned len = 1; len <= rb; len++) {
        if (len > 1) {
            unsigned half = 1u << (len - 1);
            if (half >= 4) {
                for (unsigned j = 0; j < half; j += 4) {
                    uint64_t v;
                    memcpy(&v, t + j, 8);
                    memcpy(t + half + j, &v, 8);
                }
            } else {
                for (unsigned j = 0; j < half; j++)
                    t[half + j] = t[j];
            }
        }
        for (unsigned c = 0; c < h->count[len]; c++, k++) {
            t[rc] = (uint16_t)(h->sym[k] << 6 | len);
            unsigned inc = 1u << (len - 1);
            while (rc & inc)
                inc >>= 1;
            rc = inc ? (rc & (inc - 1)) + inc : 0;
        }
    }
    return 0;
}

/* A code longer than the root table: canonically, one length after the other from the
 * root's bits + 1 (the buffer holds at least 15 bits); -1 for a bit pattern that is no code
 * (an incomplete or empty code). */
static inline unsigned pi_rev8(unsigned x);
__attribute__((noinline))
static int pi_decode_long(pi_bits *s, const pi_huff *h)
{
    unsigned x = (unsigned)s->bb;
    unsigned rev = (pi_rev8(x) << 8 | pi_rev8(x >> 8)) >> 1; /* the next 15 bits, first at
                                                                bit 14 */
    for (unsigned len = h->rbits + 1; len <= h->maxlen; len++) {
        unsigned c = (rev >> (15 - len)) - h->first[len];
        if (c < h->count[len]) {
            pi_take(s, len);
            return h->sym[h->index[len] + c];
        }
    }
    return -1;
}

/* The next symbol of h (the buffer holds at least 15 bits); -1 for a bit pattern that is no
 * code (an incomplete or empty code). */
static inline int pi_decode(pi_bits *s, const pi_huff *h)
{
    unsigned e = h->root[s->bb & h->mask];
    if (e) {
        pi_take(s, e & 63);
        return (int)(e >> 6);
    }
    return pi_decode_long(s, h);
}

/* The low 8 bits of x in reverse order. */
static inline unsigned pi_rev8(unsigned x)
{
    return (unsigned)((((x & 0xffu) * 0x80200802ull) & 0x0884422110ull) * 0x0101010101ull >> 32) &
           0xffu;
}

/* The next literal/length symbol of the fixed code (RFC 1951 3.2.6), without a table: the
 * next 9 bits in code order, then by range: 7-bit codes 0-23 are 256-279, 8-bit codes
 * 48-191 are 0-143 and 192-199 are 280-287, 9-bit codes 400-511 are 144-255. */
static inline int pi_fixed_lit(pi_bits *s)
{
    unsigned x = (unsigned)s->bb;
    unsigned c9 = pi_rev8(x) << 1 | ((x >> 8) & 1);
    if (c9 < 24u << 2) {
        pi_take(s, 7);
        return (int)(256 + (c9 >> 2));
    }
    if (c9 < 192u << 1) {
        pi_take(s, 8);
        return (int)((c9 >> 1) - 48);
    }
    if (c9 < 200u << 1) {
        pi_take(s, 8);
        return (int)(280 + (c9 >> 1) - 192);
    }
    pi_take(s, 9);
    return (int)(144 + c9 - 400);
}

/* The next distance symbol of the fixed code: 5 bits in code order (30 and 31 invalid). */
static inline int pi_fixed_dist(pi_bits *s)
{
    return (int)(pi_rev8(pi_take(s, 5)) >> 3);
}

/* Copies a match of len bytes from d bytes back (d <= o, len <= outlen - o). */
static inline void pi_copy(uint8_t *out, size_t o, size_t outlen, size_t d, unsigned len)
{
    const uint8_t *from = out + o - d;
    uint8_t *to = out + o;
    if (d >= 16 && outlen - o >= len + 16) {
        /* 16 bytes a step, each read at least 16 behind its write; up to 15 bytes past
         * the match written and later overwritten */
        for (unsigned i = 0; i < len; i += 16) {
            uint64_t v0, v1;
            memcpy(&v0, from + i, 8);
            memcpy(&v1, from + i + 8, 8);
            memcpy(to + i, &v0, 8);
            memcpy(to + i + 8, &v1, 8);
        }
    } else if (d >= 8 && outlen - o >= len + 8) {
        /* 8 bytes a step, each read at least 8 behind its write (already written even
         * when the match overlaps itself); up to 7 bytes past the match are written and
         * later overwritten (there is room) */
        for (unsigned i = 0; i < len; i += 8)
            memcpy(to + i, from + i, 8);
    } else if (outlen - o >= (size_t)len + 16) {
        /* a short distance: the first dd bytes one by one (dd the multiple of d from 8
         * to 14), then 8 bytes a step from dd behind (the same bytes: dd is a period) */
        unsigned dd = (unsigned)d * ((8 + (unsigned)d - 1) / (unsigned)d);
        for (unsigned i = 0; i < dd; i++)
            to[i] = from[i];
        for (unsigned i = dd; i < len; i += 8)
            memcpy(to + i, to + i - dd, 8);
    } else {
        for (unsigned i = 0; i < len; i++)
            to[i] = from[i];
    }
}

/* Distance code ds (0..29): the distance before its extra bits, and *nx their count (RFC 1951
 * 3.2.5). */
static inline size_t pi_dist_base(unsigned ds, unsigned *nx)
{
    if (ds < 4) {
        *nx = 0;
        return (size_t)ds + 1;
    }
    unsigned x = (ds >> 1) - 1;
    *nx = x;
    return ((size_t)(2 + (ds & 1)) << x) + 1;
}

/* Length code li (symbol - 257, 0..28): the length before its extra bits, and *nx their count
 * (RFC 1951 3.2.5). */
static inline unsigned pi_len_base(unsigned li, unsigned *nx)
{
    if (li < 8 || li == 28) {
        *nx = 0;
        return li == 28 ? 258 : 3 + li;
    }
    unsigned x = (li >> 2) - 1;
    *nx = x;
    return ((4 + (li & 3)) << x) + 3;
}

/* A length symbol's match (sym 257..285 checked here): its length's extra bits, the
 * distance code and its extra bits (the buffer is refilled first), then the copy. */
static inline int pi_match(pi_bits *s, unsigned sym, const pi_huff *dist, int fix, uint8_t *out,
                           size_t outlen, size_t *po, const char **why)
{
    size_t o = *po;
    if (s->bc < 33)
        pi_refill(s); /* length extra bits, distance code and its extra bits */
    unsigned li = sym - 257, nx;
    if (li >= 29) {
        *why = "invalid literal/length code";
        return ST_PTX_INFL_BAD;
    }
    unsigned len = pi_len_base(li, &nx); /* nx is read only after this call has set it */
    len += pi_take(s, nx);
    int ds = fix ? pi_fixed_dist(s) : pi_decode(s, dist);
    if (ds < 0 || ds >= 30) {
        *why = "invalid distance code";
        return ST_PTX_INFL_BAD;
    }
    unsigned dx;
    size_t d = pi_dist_base((unsigned)ds, &dx);
    d += pi_take(s, dx);
    if (d > o) {
        *why = "invalid distance too far back";
        return ST_PTX_INFL_BAD;
    }
    if (len > outlen - o)
        return ST_PTX_INFL_OVER;
    pi_copy(out, o, outlen, d, len);
    *po = o + len;
    return ST_PTX_INFL_OK;
}

/* The fast loop's symbol from root entry e of table tbl, on its local bit buffer (bb, bc, p):
 * the entry's symbol and length when it holds one, else pi_decode_long on the state. */
#define PI_ROOT_OR_LONG(e, sym, tbl)                                                             \
    do {                                                                                        \
        if (e) {                                                                                \
            bb >>= (e) & 63;                                                                    \
            bc -= (e) & 63;                                                                     \
            (sym) = (int)((e) >> 6);                                                            \
        } else {                                                                                \
            s->bb = bb, s->bc = bc, s->p = p;                                                   \
            (sym) = pi_decode_long(s, (tbl));                                                   \
            bb = s->bb, bc = s->bc;                                                             \
        }                                                                                       \
    } while (0)

/* Inflates one block's codes into out: with lit / dist, or the fixed code (fix, a constant
 * at each call: two copies). */
static inline int pi_codes(pi_bits *s, const pi_huff *lit, const pi_huff *dist, int fix,
                           uint8_t *out, size_t outlen, size_t *pos, const char **why)
{
    size_t o = *pos;
    if (fix) {
        for (;;) {
            if (s->bc < 15)
                pi_refill(s); /* a code: literals take several per refill */
            int sym = pi_fixed_lit(s);
            if (sym < 256) {
                if (o == outlen)
                    return ST_PTX_INFL_OVER;
                out[o++] = (uint8_t)sym;
                continue;
            }
            if (sym == 256)
                break;
            int rc = pi_match(s, (unsigned)sym, NULL, 1, out, outlen, &o, why);
            if (rc)
                return rc;
        }
    } else {
        /* the bit buffer in locals: the byte stores to out may alias *s, so with the buffer
         * in *s the compiler reloads it after every literal */
        const uint16_t *root = lit->root;
        const uint64_t mask = lit->mask;
        uint64_t bb = s->bb;
        unsigned bc = s->bc;
        const uint8_t *p = s->p, *end = s->end;
        for (;;) {
            /* the buffer refilled at every step, without a branch while 8 input bytes are
             * left (bits above bc are 0 or the next ones: OR-ing them again is harmless):
             * at least 56 bits, or 45 near the end */
            if (end - p >= 8) {
                bb |= pi_rd64le(p) << bc;
                p += (63 - bc) >> 3;
                bc |= 56;
            } else if (bc < 45) {
                s->bb = bb, s->bc = bc, s->p = p;
                pi_refill(s);
                bb = s->bb, bc = s->bc, p = s->p;
            }
            unsigned e = root[bb & mask];
            if (e - 1 < 0x3fffu) { /* literals of the root table: up to three in a row */
                bb >>= e & 63;
                bc -= e & 63;
                if (outlen - o < 3) { /* near the end of the output: one, checked */
                    if (o == outlen)
                        return ST_PTX_INFL_OVER;
                    out[o++] = (uint8_t)(e >> 6);
                    continue;
                }
                out[o++] = (uint8_t)(e >> 6);
                e = root[bb & mask];
                if (e - 1 < 0x3fffu) {
                    bb >>= e & 63;
                    bc -= e & 63;
                    out[o++] = (uint8_t)(e >> 6);
                    e = root[bb & mask];
                    if (e - 1 < 0x3fffu) {
                        bb >>= e & 63;
                        bc -= e & 63;
                        out[o++] = (uint8_t)(e >> 6);
                        continue;
                    }
                }
                /* a root literal takes at most 9 bits: at least 27 are left for e */
            }
            int sym;
            PI_ROOT_OR_LONG(e, sym, lit);
            if (sym < 256) {
                if (sym < 0) {
                    *why = "invalid literal/length code";
                    return ST_PTX_INFL_BAD;
                }
                if (o == outlen)
                    return ST_PTX_INFL_OVER;
                out[o++] = (uint8_t)sym;
                continue;
            }
            if (sym == 256)
                break;
            /* a match (pi_match's steps, on the local buffer) */
            if (bc < 33) { /* length extra bits, distance code and its extra bits */
                if (end - p >= 8) {
                    bb |= pi_rd64le(p) << bc;
                    p += (63 - bc) >> 3;
                    bc |= 56;
                } else {
                    s->bb = bb, s->bc = bc, s->p = p;
                    pi_refill(s);
                    bb = s->bb, bc = s->bc, p = s->p;
                }
            }
            unsigned li = (unsigned)sym - 257, nx;
            if (li >= 29) {
                *why = "invalid literal/length code";
                return ST_PTX_INFL_BAD;
            }
            /* two statements: the call sets nx, which the mask reads (the operands of one +
             * are unsequenced: gcc -O1 read nx before the call) */
            unsigned len = pi_len_base(li, &nx);
            len += (unsigned)(bb & ((1u << nx) - 1));
            bb >>= nx;
            bc -= nx;
            unsigned de = dist->root[bb & dist->mask];
            int ds;
            PI_ROOT_OR_LONG(de, ds, dist);
            if ((unsigned)ds >= 30) {
                *why = "invalid distance code";
                return ST_PTX_INFL_BAD;
            }
            unsigned dx;
            size_t d = pi_dist_base((unsigned)ds, &dx);
            d += (size_t)(bb & ((1u << dx) - 1));
            bb >>= dx;
            bc -= dx;
            if (d > o) {
                *why = "invalid distance too far back";
                return ST_PTX_INFL_BAD;
            }
            if (len > outlen - o)
                return ST_PTX_INFL_OVER;
            pi_copy(out, o, outlen, d, len);
            o += len;
        }
        s->bb = bb, s->bc = bc, s->p = p;
    }
    *pos = o;
    if (pi_overran(s)) {
        *why = "invalid or truncated deflate data";
        return ST_PTX_INFL_BAD;
    }
    return ST_PTX_INFL_OK;
}
#undef PI_ROOT_OR_LONG

/* The code lengths of a dynamic block, then its codes (not inlined: its tables stay off the
 * caller's frame). */
__attribute__((noinline)) STU_LOADPATH
static int pi_dynamic(pi_bits *s, uint8_t *out, size_t outlen, size_t *pos, const char **why)
{
    uint16_t lroot[1 << PI_LIT_RMAX], droot[1 << PI_DIST_RMAX], lsym[286], dsym[30];
    pi_huff lh = {.root = lroot, .sym = lsym}, dh = {.root = droot, .sym = dsym};
    pi_huff *lit = &lh, *dist = &dh;
    /* the order of the code-length code's lengths: 16 17 18 0 8 7 9 6 10 5 11 4 12 3 13 2 14
     * 1 15, five bits each in two constants (no table in memory) */
    const uint64_t ord0 = (uint64_t)16 | 17ull << 5 | 18ull << 10 | 0ull << 15 | 8ull << 20 |
                          7ull << 25 | 9ull << 30 | 6ull << 35 | 10ull << 40 | 5ull << 45 |
                          11ull << 50 | 4ull << 55;
    const uint64_t ord1 = (uint64_t)12 | 3ull << 5 | 13ull << 10 | 2ull << 15 | 14ull << 20 |
                          1ull << 25 | 15ull << 30;
    uint8_t lens[19];
    pi_refill(s);
    unsigned nlen = pi_take(s, 5) + 257, ndist = pi_take(s, 5) + 1, ncode = pi_take(s, 4) + 4;
    if (nlen > 286 || ndist > 30) {
        *why = "too many length or distance symbols";
        return ST_PTX_INFL_BAD;
    }
    memset(lens, 0, 19);
    for (unsigned i = 0; i < ncode; i++) {
        if (s->bc < 3)
            pi_refill(s);
        unsigned at = i < 12 ? (unsigned)(ord0 >> (5 * i)) & 31
                             : (unsigned)(ord1 >> (5 * (i - 12))) & 31;
        lens[at] = (uint8_t)pi_take(s, 3);
    }
    if (pi_build(lit, lens, 19, 7, PI_CODES, NULL)) {
        *why = "invalid code lengths set";
        return ST_PTX_INFL_BAD;
    }
    unsigned n = nlen + ndist;
    uint8_t cl[286 + 30];
    uint16_t cnt[2][16]; /* the literal/length and the distance lengths' counts */
    memset(cnt, 0, sizeof cnt);
    for (unsigned i = 0; i < n;) {
        if (s->bc < 14)
            pi_refill(s);
        int sym = pi_decode(s, lit);
        if (sym < 0) {
            *why = "invalid code lengths set";
            return ST_PTX_INFL_BAD;
        }
        if (sym < 16) {
            cnt[i >= nlen][sym]++;
            cl[i++] = (uint8_t)sym;
            continue;
        }
        unsigned rep;
        uint8_t v = 0;
        if (sym == 16) {
            if (i == 0) {
                *why = "invalid bit length repeat";
                return ST_PTX_INFL_BAD;
            }
            v = cl[i - 1];
            rep = 3 + pi_take(s, 2);
        } else if (sym == 17) {
            rep = 3 + pi_take(s, 3);
        } else {
            rep = 11 + pi_take(s, 7);
        }
        if (rep > n - i) {
            *why = "invalid bit length repeat";
            return ST_PTX_INFL_BAD;
        }
        for (unsigned k = 0; k < rep; k++)
            cl[i + k] = v;
        if (i + rep <= nlen || i >= nlen) {
            cnt[i >= nlen][v] = (uint16_t)(cnt[i >= nlen][v] + rep);
        } else { /* a run across the two codes' lengths */
            cnt[0][v] = (uint16_t)(cnt[0][v] + nlen - i);
            cnt[1][v] = (uint16_t)(cnt[1][v] + i + rep - nlen);
        }
        i += rep;
    }
    if (pi_overran(s)) {
        *why = "invalid or truncated deflate data";
        return ST_PTX_INFL_BAD;
    }
    if (cl[256] == 0) {
        *why = "invalid code -- missing end-of-block";
        return ST_PTX_INFL_BAD;
    }
    if (pi_build(lit, cl, nlen, PI_LIT_RMAX, PI_LIT, cnt[0])) {
        *why = "invalid literal/lengths set";
        return ST_PTX_INFL_BAD;
    }
    if (pi_build(dist, cl + nlen, ndist, PI_DIST_RMAX, PI_DIST, cnt[1])) {
        *why = "invalid distances set";
        return ST_PTX_INFL_BAD;
    }
    return pi_codes(s, lit, dist, 0, out, outlen, pos, why);
}

static int pi_fixed(pi_bits *s, uint8_t *out, size_t outlen, size_t *pos, const char **why)
{
    return pi_codes(s, NULL, NULL, 1, out, outlen, pos, why);
}

#ifdef PI_AVX2
/* The Adler-32 sums over k32 bytes (a multiple of 32, at most 5552), 32 bytes a step: b
 * gains k32 * a (the a it starts with), 32 times the bytes summed before each step, and each
 * step's bytes weighted 32..1 (pairs of bytes times weights summed into 16 bits, then into
 * 32). Sums not reduced modulo 65521 here. */
__attribute__((target("avx2")))
static void pi_adler32_avx2(const uint8_t *p, size_t k32, uint64_t *pa, uint64_t *pb)
{
    const __m256i zero = _mm256_setzero_si256();
    const __m256i w = _mm256_setr_epi8(32, 31, 30, 29, 28, 27, 26, 25, 24, 23, 22, 21, 20, 19,
                                       18, 17, 16, 15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4,
                                       3, 2, 1);
    const __m256i ones = _mm256_set1_epi16(1);
    __m256i va = zero, vp = zero, vb = zero;
    for (size_t i = 0; i < k32; i += 32) {
        __m256i v = _mm256_loadu_si256((const __m256i *)(const void *)(p + i));
        vp = _mm256_add_epi64(vp, va);
        va = _mm256_add_epi64(va, _mm256_sad_epu8(v, zero));
        vb = _mm256_add_epi32(vb, _mm256_madd_epi16(_mm256_maddubs_epi16(v, w), ones));
    }
    __m128i a2 = _mm_add_epi64(_mm256_castsi256_si128(va), _mm256_extracti128_si256(va, 1));
    __m128i p2 = _mm_add_epi64(_mm256_castsi256_si128(vp), _mm256_extracti128_si256(vp, 1));
    __m128i b4 = _mm_add_epi32(_mm256_castsi256_si128(vb), _mm256_extracti128_si256(vb, 1));
    b4 = _mm_add_epi32(b4, _mm_shuffle_epi32(b4, _MM_SHUFFLE(1, 0, 3, 2)));
    b4 = _mm_add_epi32(b4, _mm_shuffle_epi32(b4, _MM_SHUFFLE(2, 3, 0, 1)));
    uint64_t sa = (uint64_t)_mm_cvtsi128_si64(a2) +
                  (uint64_t)_mm_cvtsi128_si64(_mm_unpackhi_epi64(a2, a2));
    uint64_t sp = (uint64_t)_mm_cvtsi128_si64(p2) +
                  (uint64_t)_mm_cvtsi128_si64(_mm_unpackhi_epi64(p2, p2));
    *pb += *pa * k32 + 32 * sp + (uint32_t)_mm_cvtsi128_si32(b4);
    *pa += sa;
}
#endif

static uint32_t pi_adler32(const uint8_t *p, size_t n)
{
    uint64_t a = 1, b = 0;
#ifdef PI_AVX2
    int avx2 = n >= 64 && __builtin_cpu_supports("avx2"); /* what libgcc found at start-up */
#endif
    while (n) {
        size_t k = n < 5552 ? n : 5552; /* the most bytes before b can overflow 32 bits */
        n -= k;
#ifdef PI_AVX2
        if (avx2 && k >= 32) {
            size_t k32 = k & ~(size_t)31;
            pi_adler32_avx2(p, k32, &a, &b);
            p += k32;
            k -= k32;
        }
#endif
#if defined(__SSE2__)
        /* 16 bytes a step: over a chunk of k bytes b gains k * a (the a it starts with),
         * 16 times the bytes summed before each step, and each step's bytes weighted 16..1 */
        size_t k16 = k & ~(size_t)15;
        if (k16) {
            const __m128i zero = _mm_setzero_si128();
            const __m128i wlo = _mm_setr_epi16(16, 15, 14, 13, 12, 11, 10, 9);
            const __m128i whi = _mm_setr_epi16(8, 7, 6, 5, 4, 3, 2, 1);
            __m128i va = zero, vp = zero, vb = zero;
            b += a * k16;
            for (size_t i = 0; i < k16; i += 16) {
                __m128i v = _mm_loadu_si128((const __m128i *)(const void *)(p + i));
                vp = _mm_add_epi64(vp, va);
                va = _mm_add_epi64(va, _mm_sad_epu8(v, zero));
                vb = _mm_add_epi32(vb, _mm_madd_epi16(_mm_unpacklo_epi8(v, zero), wlo));
                vb = _mm_add_epi32(vb, _mm_madd_epi16(_mm_unpackhi_epi8(v, zero), whi));
            }
            uint64_t sa = (uint64_t)_mm_cvtsi128_si64(va) +
                          (uint64_t)_mm_cvtsi128_si64(_mm_unpackhi_epi64(va, va));
            uint64_t sp = (uint64_t)_mm_cvtsi128_si64(vp) +
                          (uint64_t)_mm_cvtsi128_si64(_mm_unpackhi_epi64(vp, vp));
            vb = _mm_add_epi32(vb, _mm_shuffle_epi32(vb, _MM_SHUFFLE(1, 0, 3, 2)));
            vb = _mm_add_epi32(vb, _mm_shuffle_epi32(vb, _MM_SHUFFLE(2, 3, 0, 1)));
            b += 16 * sp + (uint32_t)_mm_cvtsi128_si32(vb);
            a += sa;
            p += k16;
            k -= k16;
        }
#endif
        for (; k; k--) {
            a += *p++;
            b += a;
        }
        a %= 65521;
        b %= 65521;
    }
    return (uint32_t)(b << 16 | a);
}

/* Inflates the zlib stream at in (inlen bytes, header included) into out (outlen bytes). */
STU_LOADPATH
static int st_ptx_inflate(const uint8_t *in, size_t inlen, uint8_t *out, size_t outlen,
                          size_t *got, const char **why)
{
    pi_bits s = {.p = in + (inlen < 2 ? inlen : 2), .end = in + inlen};
    size_t o = 0;
    *got = 0;
    *why = "invalid or truncated deflate data";
    int last;
    do {
        pi_refill(&s);
        last = (int)pi_take(&s, 1);
        unsigned type = pi_take(&s, 2);
        int rc;
        if (type == 0) {
            const uint8_t *q = pi_align(&s);
            if (!q || s.end - q < 4) {
                *why = "invalid or truncated deflate data";
                return ST_PTX_INFL_BAD;
            }
            unsigned len = q[0] | (unsigned)q[1] << 8, nlen = q[2] | (unsigned)q[3] << 8;
            if (len != (~nlen & 0xffffu)) {
                *why = "invalid stored block lengths";
                return ST_PTX_INFL_BAD;
            }
            q += 4;
            if ((size_t)(s.end - q) < len) {
                *why = "invalid or truncated deflate data";
                return ST_PTX_INFL_BAD;
            }
            if (len > outlen - o)
                return ST_PTX_INFL_OVER;
            memcpy(out + o, q, len);
            o += len;
            s.p = q + len;
            s.bb = 0;
            s.bc = 0;
            s.over = 0;
            rc = ST_PTX_INFL_OK;
        } else if (type == 1) {
            rc = pi_fixed(&s, out, outlen, &o, why);
        } else if (type == 2) {
            rc = pi_dynamic(&s, out, outlen, &o, why);
        } else {
            *why = "invalid block type";
            return ST_PTX_INFL_BAD;
        }
        if (rc)
            return rc;
    } while (!last);
    const uint8_t *q = pi_align(&s);
    if (!q || s.end - q < 4) {
        *why = "truncated: no check value";
        return ST_PTX_INFL_BAD;
    }
    uint32_t want = (uint32_t)q[0] << 24 | (uint32_t)q[1] << 16 | (uint32_t)q[2] << 8 | q[3];
    if (pi_adler32(out, o) != want) {
        *why = "incorrect data check";
        return ST_PTX_INFL_BAD;
    }
    *got = o;
    return ST_PTX_INFL_OK;
}

#endif
