/* util/json_str.h - a JSON string literal from arbitrary bytes, libc only.
 *
 * Owns: the one JSON string escaper of seamtex (the daemon's JSON log lines use it; any JSON
 * writer should). Input is any byte string (it need not be UTF-8 nor NUL-free); output is
 * always valid JSON and valid UTF-8: '"' and '\' escaped, control characters (U+0000..U+001F,
 * and U+007F) written as \uXXXX (\n \r \t \b \f as their short forms), each byte that is not
 * part of a well-formed UTF-8 sequence (overlong forms, surrogates, code points past
 * U+10FFFF, truncated sequences) replaced by U+FFFD. Well-formed UTF-8 passes through.
 * Does not own: JSON numbers, objects (callers write those with printf).
 */
#ifndef STU_JSON_STR_H
#define STU_JSON_STR_H

#include <stddef.h>

/* Writes the quoted, escaped form of s[0..len) into out (cap bytes, NUL-terminated when cap >
 * 0), like snprintf: returns the length the whole literal needs (quotes included, NUL not),
 * so a return >= cap means it was cut (a cut never splits an escape or a UTF-8 sequence; the
 * closing quote is then missing). At most 6 * len + 2 bytes. */
size_t stu_json_str(char *out, size_t cap, const char *s, size_t len);

#endif
