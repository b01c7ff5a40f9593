/* tests/unit/test_ptex_inflate.c - the Ptex reader's small-stream inflater (ptex_inflate.h)
 * against zlib, the inflater Ptex itself reads with: every stream zlib's deflate makes
 * (stored, fixed and dynamic blocks, one or several, every level and strategy, sizes 0 to
 * 20 000 bytes) inflates to its input; streams with flipped bits, cut short, overwritten
 * bytes or a wrong declared size give exactly zlib's outcome (refused, or the same bytes);
 * hand-made streams get the named refusals. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ptex_inflate.h"

static uint64_t rs = 88172645463325252ull;
static unsigned rnd(void)
{
    rs ^= rs << 13;
    rs ^= rs >> 7;
    rs ^= rs << 17;
    return (unsigned)rs;
}

enum { MAXN = 20000, MAXZ = MAXN + MAXN / 8 + 256 };
static uint8_t src[MAXN], z[MAXZ], got[MAXN + 64], want[MAXN + 64];

/* n bytes of one of four kinds of data (noise of a small alphabet, slow ramps, repeats
 * near by, runs with rare noise) */
static void fill(size_t n, unsigned kind)
{
    unsigned alpha = 1 + rnd() % 255;
    for (size_t i = 0; i < n; i++) {
        if (kind == 0)
            src[i] = (uint8_t)(rnd() % alpha);
        else if (kind == 1)
            src[i] = (uint8_t)(i ? src[i - 1] + (rnd() % 3 == 0) : 0);
        else if (kind == 2)
            src[i] = (uint8_t)(i >= 7 && rnd() % 4 ? src[i - 1 - rnd() % 7] : rnd());
        else
            src[i] = (uint8_t)(rnd() % 16 == 0 ? rnd() : 'a');
    }
}

/* zlib's deflate of src[0, n): level, strategy, and optionally a full flush halfway (two or
 * more blocks, an empty stored block between them) */
static size_t zip(size_t n, int level, int strategy, int split)
{
    z_stream zs;
    memset(&zs, 0, sizeof zs);
    assert_int_equal(deflateInit2(&zs, level, Z_DEFLATED, 15, 1 + (int)(rnd() % 9), strategy),
                     Z_OK);
    zs.next_in = src;
    zs.next_out = z;
    zs.avail_out = MAXZ;
    if (split && n > 1) {
        zs.avail_in = (uInt)(n / 2);
        assert_int_equal(deflate(&zs, Z_FULL_FLUSH), Z_OK);
        zs.avail_in = (uInt)(n - n / 2);
    } else {
        zs.avail_in = (uInt)n;
    }
    assert_int_equal(deflate(&zs, Z_FINISH), Z_STREAM_END);
    size_t zl = MAXZ - zs.avail_out;
    deflateEnd(&zs);
    return zl;
}

/* zlib's inflate of z[0, zl) into want (outlen bytes): 1 and *n when it ends the stream */
static int zlib_ok(size_t zl, size_t outlen, size_t *n)
{
    z_stream is;
    memset(&is, 0, sizeof is);
    assert_int_equal(inflateInit(&is), Z_OK);
    is.next_in = z;
    is.avail_in = (uInt)zl;
    is.next_out = want;
    is.avail_out = (uInt)outlen;
    int r = inflate(&is, Z_FINISH);
    *n = outlen - is.avail_out;
    inflateEnd(&is);
    return r == Z_STREAM_END;
}

static const int strategies[] = {Z_DEFAULT_STRATEGY, Z_FILTERED, Z_HUFFMAN_ONLY, Z_RLE, Z_FIXED};

static void inflates_every_stream_zlib_makes(void **state)
{
    (void)state;
    size_t streams = 0;
    for (int it = 0; it < 3000; it++) {
        size_t n = it % 7 == 0 ? rnd() % MAXN : rnd() % 1200;
        if (it < 40)
            n = (size_t)it; /* 0.. 39 bytes: the tiny streams of small files */
        fill(n, rnd() % 4);
        size_t zl = zip(n, (int)(rnd() % 10), strategies[rnd() % 5], rnd() % 3 == 0);
        size_t g = 12345;
        const char *why = NULL;
        memset(got, 0xa5, n + 1);
        int rc = st_ptx_inflate(z, zl, got, n, &g, &why);
        if (rc != ST_PTX_INFL_OK || g != n)
            fail_msg("stream %d (%zu bytes, %zu zipped): rc %d (%s), %zu bytes", it, n, zl, rc,
                     why ? why : "", g);
        assert_memory_equal(got, src, n);
        assert_int_equal(got[n], 0xa5); /* nothing written past the output */
        streams++;
    }
    assert_int_equal(streams, 3000);
}

static void damaged_streams_get_zlibs_outcome(void **state)
{
    (void)state;
    size_t refused = 0, accepted = 0;
    for (int it = 0; it < 8000; it++) {
        size_t n = rnd() % 5 == 0 ? rnd() % MAXN : rnd() % 1500;
        fill(n, rnd() % 4);
        size_t zl = zip(n, (int)(rnd() % 10), strategies[rnd() % 5], rnd() % 3 == 0);
        size_t outlen = n;
        switch (rnd() % 5) {
        case 0: /* flipped bits past the zlib header (the reader checks the header first) */
            for (int k = 1 + (int)(rnd() % 4); k > 0; k--)
                if (zl > 2)
                    z[2 + rnd() % (zl - 2)] ^= (uint8_t)(1u << (rnd() % 8));
            break;
        case 1: /* cut short */
            zl = 2 + rnd() % (zl - 1);
            break;
        case 2: /* declared smaller */
            outlen = n ? n - 1 - rnd() % n : 0;
            break;
        case 3: /* declared larger */
            outlen = n + 1 + rnd() % 40;
            break;
        default: /* one byte overwritten */
            if (zl > 2)
                z[2 + rnd() % (zl - 2)] = (uint8_t)rnd();
            break;
        }
        size_t zn = 0, g = 0;
        const char *why = "";
        int zok = zlib_ok(zl, outlen, &zn);
        int rc = st_ptx_inflate(z, zl, got, outlen, &g, &why);
        if ((rc == ST_PTX_INFL_OK) != zok)
            fail_msg("stream %d: ours %d (%s), zlib %s", it, rc, why,
                     zok ? "accepts it" : "refuses it");
        if (zok) {
            assert_int_equal(g, zn);
            assert_memory_equal(got, want, zn);
            accepted++;
        } else {
            assert_non_null(why);
            refused++;
        }
    }
    assert_true(refused > 500 && accepted > 500);
}

/* a stream written bit by bit, LSB first, after a zlib header */
typedef struct bw {
    uint8_t b[64];
    size_t n;
    unsigned bit;
} bw;

static void put(bw *w, unsigned v, unsigned nbits)
{
    for (unsigned i = 0; i < nbits; i++) {
        if (!w->bit)
            w->b[w->n++] = 0;
        w->b[w->n - 1] |= (uint8_t)(((v >> i) & 1) << w->bit);
        w->bit = (w->bit + 1) & 7;
    }
}

/* a Huffman code of nbits, most significant bit first */
static void put_code(bw *w, unsigned code, unsigned nbits)
{
    for (unsigned i = nbits; i-- > 0;)
        put(w, (code >> i) & 1, 1);
}

static void start(bw *w)
{
    memset(w, 0, sizeof *w);
    w->b[0] = 0x78;
    w->b[1] = 0x01;
    w->n = 2;
}

static void adler_of(bw *w, const uint8_t *p, size_t n)
{
    uint32_t a = 1, b = 0;
    for (size_t i = 0; i < n; i++) {
        a = (a + p[i]) % 65521;
        b = (b + a) % 65521;
    }
    uint32_t v = b << 16 | a;
    w->bit = 0;
    for (int i = 3; i >= 0; i--)
        w->b[w->n++] = (uint8_t)(v >> (8 * i));
}

static void expect_refused(const bw *w, size_t outlen, const char *reason)
{
    size_t g = 0;
    const char *why = NULL;
    assert_int_equal(st_ptx_inflate(w->b, w->n, got, outlen, &g, &why), ST_PTX_INFL_BAD);
    assert_string_equal(why, reason);
}

static void hand_made_streams_get_their_refusals(void **state)
{
    (void)state;
    bw w;
    /* a fixed block "ab" that is right: accepted */
    start(&w);
    put(&w, 1, 1);
    put(&w, 1, 2);
    put_code(&w, 0x30 + 'a', 8);
    put_code(&w, 0x30 + 'b', 8);
    put_code(&w, 0, 7); /* end of block */
    adler_of(&w, (const uint8_t *)"ab", 2);
    size_t g = 0;
    const char *why = NULL;
    assert_int_equal(st_ptx_inflate(w.b, w.n, got, 2, &g, &why), ST_PTX_INFL_OK);
    assert_int_equal(g, 2);
    assert_memory_equal(got, "ab", 2);
    /* one byte declared: more than declared */
    assert_int_equal(st_ptx_inflate(w.b, w.n, got, 1, &g, &why), ST_PTX_INFL_OVER);
    /* its check value changed */
    w.b[w.n - 1] ^= 1;
    expect_refused(&w, 2, "incorrect data check");
    /* without its check value */
    w.n -= 4;
    expect_refused(&w, 2, "truncated: no check value");

    /* block type 3 */
    start(&w);
    put(&w, 1, 1);
    put(&w, 3, 2);
    expect_refused(&w, 4, "invalid block type");
    /* a stored block whose length's complement is wrong */
    start(&w);
    put(&w, 1, 1);
    put(&w, 0, 2);
    w.bit = 0;
    w.b[w.n++] = 2;
    w.b[w.n++] = 0;
    w.b[w.n++] = 0xfd;
    w.b[w.n++] = 0xfe; /* ~2 is 0xfffd: this says 0xfefd */
    w.b[w.n++] = 'a';
    w.b[w.n++] = 'b';
    expect_refused(&w, 2, "invalid stored block lengths");
    /* a length and distance with nothing before it */
    start(&w);
    put(&w, 1, 1);
    put(&w, 1, 2);
    put_code(&w, 1, 7); /* 257: length 3 */
    put_code(&w, 0, 5); /* distance 1 */
    put_code(&w, 0, 7);
    expect_refused(&w, 8, "invalid distance too far back");
    /* literal/length symbol 286 (a code of the fixed code, no symbol) */
    start(&w);
    put(&w, 1, 1);
    put(&w, 1, 2);
    put_code(&w, 0xc0 + 6, 8); /* 286 */
    expect_refused(&w, 8, "invalid literal/length code");
    /* distance symbol 30 */
    start(&w);
    put(&w, 1, 1);
    put(&w, 1, 2);
    put_code(&w, 0x30 + 'a', 8);
    put_code(&w, 1, 7);  /* length 3 */
    put_code(&w, 30, 5); /* distance code 30 */
    expect_refused(&w, 8, "invalid distance code");
    /* a dynamic block whose code-length code repeats the previous length at the start */
    start(&w);
    put(&w, 1, 1);
    put(&w, 2, 2);
    put(&w, 0, 5); /* 257 literal/length codes */
    put(&w, 0, 5); /* 1 distance code */
    put(&w, 0, 4); /* 4 code-length code lengths, for 16 17 18 0 */
    put(&w, 1, 3); /* 16: length 1 */
    put(&w, 0, 3);
    put(&w, 0, 3);
    put(&w, 1, 3); /* 0: length 1 (a complete code: 0 -> "0", 16 -> "1") */
    put_code(&w, 1, 1); /* 16 first: nothing to repeat */
    put(&w, 0, 2);
    expect_refused(&w, 8, "invalid bit length repeat");
    /* the same with lengths that over-subscribe the code-length code */
    start(&w);
    put(&w, 1, 1);
    put(&w, 2, 2);
    put(&w, 0, 5);
    put(&w, 0, 5);
    put(&w, 0, 4);
    put(&w, 1, 3);
    put(&w, 1, 3);
    put(&w, 0, 3);
    put(&w, 1, 3); /* three codes of length 1 */
    put(&w, 0, 8);
    expect_refused(&w, 8, "invalid code lengths set");
    /* a dynamic block whose literal/length code is incomplete (two codes of length 2: zlib
     * allows an incomplete code only as a single code of length 1) */
    start(&w);
    put(&w, 1, 1);
    put(&w, 2, 2);
    put(&w, 0, 5);  /* 257 literal/length codes */
    put(&w, 0, 5);  /* 1 distance code */
    put(&w, 14, 4); /* 18 code-length code lengths: up to the one for 1 */
    {
        /* for 16 17 18 0 8 7 9 6 10 5 11 4 12 3 13 2 14 1: 0 -> 00, 1 -> 01, 2 -> 10, 18 -> 11 */
        static const unsigned cll[18] = {0, 0, 2, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 2};
        for (int i = 0; i < 18; i++)
            put(&w, cll[i], 3);
    }
    put_code(&w, 2, 2);  /* literal 0: length 2 */
    put_code(&w, 3, 2);  /* 18: 138 zeros */
    put(&w, 127, 7);
    put_code(&w, 3, 2);  /* 18: 117 zeros (literals 1-255 done) */
    put(&w, 106, 7);
    put_code(&w, 2, 2);  /* 256: length 2 */
    put_code(&w, 1, 2);  /* the distance code: length 1 */
    put(&w, 0, 8);
    expect_refused(&w, 8, "invalid literal/lengths set");
    /* a fixed block cut inside its codes */
    start(&w);
    put(&w, 1, 1);
    put(&w, 1, 2);
    put_code(&w, 0x30 + 'a', 8);
    expect_refused(&w, 8, "invalid or truncated deflate data");
}

/* Matches from far back (distance codes 24-29, 11-13 extra bits): noise, then the same noise
 * again d0 bytes later, with a few bytes changed so that it is several matches */
static void far_matches(void **state)
{
    (void)state;
    static const size_t d0s[] = {2100, 3000, 7000, 9000, 12000, 16000, 16385, 19990};
    for (size_t t = 0; t < sizeof d0s / sizeof d0s[0]; t++) {
        size_t n = MAXN, d0 = d0s[t];
        for (size_t i = 0; i < n; i++)
            src[i] = (uint8_t)(i < d0 || rnd() % 97 == 0 ? rnd() : src[i - d0]);
        size_t zl = zip(n, 6, Z_DEFAULT_STRATEGY, 0);
        size_t g = 0;
        const char *why = NULL;
        memset(got, 0xa5, n + 1);
        assert_int_equal(st_ptx_inflate(z, zl, got, n, &g, &why), ST_PTX_INFL_OK);
        assert_int_equal(g, n);
        assert_memory_equal(got, src, n);
        assert_int_equal(got[n], 0xa5);
    }
}

/* canonical codes (RFC 1951 3.2.2) of n code lengths */
static void canon(const uint8_t *lens, unsigned n, unsigned *codes)
{
    unsigned cnt[16] = {0}, next[16];
    for (unsigned i = 0; i < n; i++)
        cnt[lens[i]]++;
    cnt[0] = 0;
    unsigned c = 0;
    for (unsigned l = 1; l < 16; l++) {
        c = (c + cnt[l - 1]) << 1;
        next[l] = c;
    }
    for (unsigned i = 0; i < n; i++)
        codes[i] = lens[i] ? next[lens[i]]++ : 0;
}

/* Dynamic blocks whose code-length sequence repeats a length (code 16) across the end of
 * the literal/length lengths into the distance lengths (RFC 1951 allows it; zlib's deflate
 * never writes it), or from exactly the first distance length on: both inflate to "abaaba". */
static void dynamic_repeats_across_the_two_codes(void **state)
{
    (void)state;
    enum { NLEN = 260, NDIST = 8 };
    /* literal/length: 'a' 2, 'b' 3, 256 2, 257-259 3 (complete); distance: 8 codes of 3 */
    uint8_t lens[NLEN + NDIST] = {0};
    lens['a'] = 2;
    lens['b'] = 3;
    lens[256] = 2;
    lens[257] = lens[258] = lens[259] = 3;
    for (int i = 0; i < NDIST; i++)
        lens[NLEN + i] = 3;
    unsigned lc[NLEN], dc[NDIST];
    canon(lens, NLEN, lc);
    canon(lens + NLEN, NDIST, dc);
    /* the code-length code: 0, 3, 16 of 2 bits, 2 and 18 of 3 (complete) */
    uint8_t cll[19] = {0};
    cll[0] = cll[3] = cll[16] = 2;
    cll[2] = cll[18] = 3;
    unsigned cc[19];
    canon(cll, 19, cc);
    static const uint8_t order[19] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2,
                                      14, 1, 15};
    for (int variant = 0; variant < 2; variant++) {
        bw w;
        start(&w);
        put(&w, 1, 1);
        put(&w, 2, 2);
        put(&w, NLEN - 257, 5);
        put(&w, NDIST - 1, 5);
        put(&w, 19 - 4, 4);
        for (int i = 0; i < 19; i++)
            put(&w, cll[order[i]], 3);
        put_code(&w, cc[18], cll[18]); /* 97 zeros */
        put(&w, 97 - 11, 7);
        put_code(&w, cc[2], cll[2]);   /* 'a' */
        put_code(&w, cc[3], cll[3]);   /* 'b' */
        put_code(&w, cc[18], cll[18]); /* 138 zeros */
        put(&w, 127, 7);
        put_code(&w, cc[18], cll[18]); /* 19 zeros: up to 255 */
        put(&w, 19 - 11, 7);
        put_code(&w, cc[2], cll[2]);   /* 256 */
        if (variant == 0) {
            put_code(&w, cc[3], cll[3]);   /* 257 */
            put_code(&w, cc[16], cll[16]); /* 258, 259, distance 0-3: across the end */
            put(&w, 6 - 3, 2);
            put_code(&w, cc[16], cll[16]); /* distance 4-6 */
            put(&w, 3 - 3, 2);
            put_code(&w, cc[3], cll[3]);   /* distance 7 */
        } else {
            for (int i = 0; i < 3; i++)
                put_code(&w, cc[3], cll[3]); /* 257-259 */
            put_code(&w, cc[16], cll[16]);   /* distance 0-5: from the first on */
            put(&w, 6 - 3, 2);
            put_code(&w, cc[3], cll[3]);     /* distance 6, 7 */
            put_code(&w, cc[3], cll[3]);
        }
        put_code(&w, lc['a'], 2);
        put_code(&w, lc['b'], 3);
        put_code(&w, lc['a'], 2);
        put_code(&w, lc[257], 3); /* length 3 */
        put_code(&w, dc[2], 3);   /* distance 3 */
        put_code(&w, lc[256], 2);
        adler_of(&w, (const uint8_t *)"abaaba", 6);
        size_t g = 0;
        const char *why = NULL;
        assert_int_equal(st_ptx_inflate(w.b, w.n, got, 6, &g, &why), ST_PTX_INFL_OK);
        assert_int_equal(g, 6);
        assert_memory_equal(got, "abaaba", 6);
        /* zlib agrees */
        memcpy(z, w.b, w.n);
        size_t zn = 0;
        assert_true(zlib_ok(w.n, 6, &zn));
        assert_int_equal(zn, 6);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(dynamic_repeats_across_the_two_codes),
        cmocka_unit_test(far_matches),
        cmocka_unit_test(inflates_every_stream_zlib_makes),
        cmocka_unit_test(damaged_streams_get_zlibs_outcome),
        cmocka_unit_test(hand_made_streams_get_their_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
