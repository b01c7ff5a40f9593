/* util/json_str.c - JSON string literals from arbitrary bytes (json_str.h).
 *
 * UTF-8 well-formedness follows the table of RFC 3629 section 4: the first byte decides the
 * length and the allowed range of the second byte (E0: A0..BF, ED: 80..9F, F0: 90..BF,
 * F4: 80..8F, otherwise 80..BF); any other byte starts no sequence.
 */
#include "json_str.h"

#include <string.h>

/* Length of the well-formed UTF-8 sequence at s (n bytes left), 0 when there is none. */
static size_t utf8_len(const unsigned char *s, size_t n)
{
    unsigned c = s[0];
    size_t len;
    unsigned lo = 0x80, hi = 0xBF;
    if (c < 0x80)
        return 1;
    if (c >= 0xC2 && c <= 0xDF)
        len = 2;
    else if (c >= 0xE0 && c <= 0xEF) {
        len = 3;
        if (c == 0xE0)
            lo = 0xA0;
        else if (c == 0xED)
            hi = 0x9F;                   /* no UTF-16 surrogates */
    } else if (c >= 0xF0 && c <= 0xF4) {
        len = 4;
        if (c == 0xF0)
            lo = 0x90;
        else if (c == 0xF4)
            hi = 0x8F;                   /* nothing past U+10FFFF */
    } else
        return 0;                        /* 80..C1 (continuation, overlong), F5..FF */
    if (n < len || s[1] < lo || s[1] > hi)
        return 0;
    for (size_t i = 2; i < len; i++)
        if (s[i] < 0x80 || s[i] > 0xBF)
            return 0;
    return len;
}

/* Appends piece (k bytes) when it fits whole; counts it either way. */
static void emit(char *out, size_t cap, size_t *need, int *cut, const char *piece, size_t k)
{
    if (!*cut && *need + k < cap)
        memcpy(out + *need, piece, k);
    else
        *cut = 1;
    *need += k;
}

size_t stu_json_str(char *out, size_t cap, const char *s, size_t len)
{
    static const char hex[] = "0123456789abcdef";
    const unsigned char *p = (const unsigned char *)s;
    size_t need = 0, i = 0, kept = 0;
    int cut = 0;
    emit(out, cap, &need, &cut, "\"", 1);
    while (i < len) {
        char esc[8];
        size_t k = 0;
        unsigned c = p[i];
        size_t u = utf8_len(p + i, len - i);
        if (u > 1) {
            emit(out, cap, &need, &cut, (const char *)p + i, u);
            if (!cut)
                kept = need;
            i += u;
            continue;
        }
        if (u == 0) {
            memcpy(esc, "\xEF\xBF\xBD", 3);   /* U+FFFD for one stray byte */
            k = 3;
        } else if (c == '"' || c == '\\') {
            esc[0] = '\\';
            esc[1] = (char)c;
            k = 2;
        } else if (c == '\n' || c == '\r' || c == '\t' || c == '\b' || c == '\f') {
            esc[0] = '\\';
            esc[1] = c == '\n' ? 'n' : c == '\r' ? 'r' : c == '\t' ? 't' : c == '\b' ? 'b' : 'f';
            k = 2;
        } else if (c < 0x20 || c == 0x7F) {
            memcpy(esc, "\\u00", 4);
            esc[4] = hex[c >> 4];
            esc[5] = hex[c & 15];
            k = 6;
        } else {
            esc[0] = (char)c;
            k = 1;
        }
        emit(out, cap, &need, &cut, esc, k);
        if (!cut)
            kept = need;
        i++;
    }
    emit(out, cap, &need, &cut, "\"", 1);
    if (!cut)
        kept = need;
    if (cap)
        out[kept < cap ? kept : cap - 1] = 0;
    return need;
}
