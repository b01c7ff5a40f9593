/* protocol/stp_name.h - the set-name rule (PROTOCOL.md section 1), the one implementation.
 *
 * Owns: STP_MAX_NAME and the check every set name goes through: 1..255 bytes, each byte in
 * [A-Za-z0-9._-], the first byte not '.'. A valid name is therefore a plain file name on any
 * POSIX file system (never "", "." or "..", never hidden, no '/', no NUL, ASCII only, at most
 * NAME_MAX = 255 bytes), which is what the data dir needs: each set is the directory
 * <data-dir>/sets/<name>.
 * Users: the daemon's request decoders (protocol/bodies.c: a bad name is INVALID), the
 * registry and data dir (store/registry.c st_name_check), libseamtex (refuses to send a bad
 * name). Header-only and needing only <stddef.h>, so that store/ can apply the same rule
 * without linking protocol/.
 * Does not own: what a name refers to (the registry), limits on how many names there are.
 */
#ifndef STP_NAME_H
#define STP_NAME_H

#include <stddef.h>

#define STP_MAX_NAME 255   /* bytes, not counting a NUL */

/* What is wrong with a name (0 = nothing). */
enum stp_name_problem {
    STP_NAME_OK       = 0,
    STP_NAME_EMPTY    = 1,
    STP_NAME_TOO_LONG = 2,   /* more than STP_MAX_NAME bytes */
    STP_NAME_DOT      = 3,   /* starts with '.' */
    STP_NAME_BAD_BYTE = 4    /* a byte outside [A-Za-z0-9._-] (NUL, '/', space, >= 0x80 ...) */
};

/* Checks the n bytes at p (p may be NULL when n is 0) and returns the first problem found, in
 * the order of the enum; *at (may be NULL) gets the offset of the first bad byte. */
static inline int stp_name_check(const void *p, size_t n, size_t *at)
{
    const unsigned char *s = (const unsigned char *)p;
    if (n == 0 || !s)
        return STP_NAME_EMPTY;
    if (n > STP_MAX_NAME)
        return STP_NAME_TOO_LONG;
    if (s[0] == '.')
        return STP_NAME_DOT;
    for (size_t i = 0; i < n; i++) {
        unsigned c = s[i];
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '.' || c == '_' || c == '-')) {
            if (at)
                *at = i;
            return STP_NAME_BAD_BYTE;
        }
    }
    return STP_NAME_OK;
}

/* 1 when the n bytes at p are a valid set name. */
static inline int stp_name_valid(const void *p, size_t n)
{
    return stp_name_check(p, n, NULL) == STP_NAME_OK;
}

/* The same for a NUL-terminated string (NULL is not valid). Looks at most STP_MAX_NAME + 1
 * bytes. */
static inline int stp_name_valid_cstr(const char *s)
{
    size_t n = 0;
    if (!s)
        return 0;
    while (n <= STP_MAX_NAME && s[n])
        n++;
    return stp_name_valid(s, n);
}

/* Texts for the problems of a name field, indexed by enum stp_name_problem; field is a string
 * literal ("set", "target"). */
#define STP_NAME_TEXTS(field)                                                            \
    { "", field " name is empty", field " name is longer than 255 bytes",                \
      field " name must not start with '.'",                                            \
      field " name may only hold the bytes A-Z a-z 0-9 . _ -" }

/* A sentence for a problem, e.g. "set name must not start with '.'"; "" for STP_NAME_OK. */
static inline const char *stp_name_problem_text(int problem)
{
    static const char *const texts[] = STP_NAME_TEXTS("set");
    return problem >= 0 && problem <= STP_NAME_BAD_BYTE ? texts[problem] : texts[STP_NAME_BAD_BYTE];
}

#endif
