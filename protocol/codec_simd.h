/* protocol/codec_simd.h - the two implementations of the per-value codecs on the sampling hot
 * path: the portable reference loops (the definition of every result) and their AVX2 + F16C
 * forms (codec_avx2.c), bit for bit the same for every input. For the dispatching entry points
 * (compact.c, bodies.c: stp_f16_encode, stp_f16_decode, stp_enc_sample_values,
 * stp_sample_queries_f32, stp_put_queries_uv16) and for the tests and benchmarks that
 * compare the two.
 *
 * Owns: these declarations only. Not part of the public protocol API (proto.h).
 */
#ifndef STP_CODEC_SIMD_H
#define STP_CODEC_SIMD_H

#include <stddef.h>
#include <stdint.h>

#include "proto.h"

/* n queries in the UV16 layout (PROTOCOL.md 4.4.1; face16: UV16 + FACE16, 14 bytes a query,
 * else 16) at out: what stp_put_queries writes for those flags. Dispatches like the others. */
void stp_put_queries_uv16(const stp_query *q, size_t n, int face16, uint8_t *out);

/* 1 when this CPU runs the *_avx2 functions below (x86-64 with AVX2 and F16C), else 0; cheap
 * (reads what was found once). On other CPUs the *_avx2 functions run the scalar loops. */
int stp_codec_have_avx2(void);

/* The portable references. */
void stp_f16_encode_scalar(const float *v, size_t n, uint8_t *out);   /* compact.c */
void stp_f16_decode_scalar(const uint8_t *p, size_t n, float *out);   /* compact.c */
void stp_sample_queries_f32_scalar(const stp_sample_req *r, uint32_t first, uint32_t n,
                                   uint8_t *out);                      /* compact.c */
void stp_put_queries_uv16_scalar(const stp_query *q, size_t n, int face16,
                                 uint8_t *out);                        /* compact.c */
void stp_unorm8_encode_scalar(const float *v, size_t n, uint8_t *out);  /* bodies.c */
void stp_unorm16_encode_scalar(const float *v, size_t n, uint8_t *out); /* bodies.c */

/* The same with AVX2 + F16C (codec_avx2.c); call only when stp_codec_have_avx2(). Any n,
 * pointers of any alignment; nothing is read or written outside the n values. */
void stp_f16_encode_avx2(const float *v, size_t n, uint8_t *out);
void stp_f16_decode_avx2(const uint8_t *p, size_t n, float *out);
void stp_sample_queries_f32_avx2(const stp_sample_req *r, uint32_t first, uint32_t n,
                                 uint8_t *out);
void stp_put_queries_uv16_avx2(const stp_query *q, size_t n, int face16, uint8_t *out);
void stp_unorm8_encode_avx2(const float *v, size_t n, uint8_t *out);
void stp_unorm16_encode_avx2(const float *v, size_t n, uint8_t *out);

#endif
