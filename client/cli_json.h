/* client/cli_json.h - the one JSON writer of the command-line client (`seamtex ... --json`).
 *
 * Owns: writing one JSON document to a FILE: objects, arrays, strings (escaped: '"', '\\',
 * control bytes as \u00XX, bytes that are not valid UTF-8 replaced by U+FFFD, so the output
 * is always valid UTF-8 JSON whatever a server message or metadata string holds), integers
 * written exactly (u64 / i64 in decimal), doubles with 17 significant digits (they read
 * back to the same double; NaN and infinities, which JSON cannot hold, become null), booleans.
 * Does not own: what the commands put in it (seamtex_cli.c, cli_transfer.c; keys documented in
 * docs/client.md and seamtex(1)).
 *
 * Usage: cli_json_begin, then values; inside an object every value takes a key, inside an
 * array (or at the top) the key is NULL. Nesting is at most CLI_JSON_DEPTH deep; the writer
 * keeps no state outside the struct the caller owns. cli_json_end writes the final newline
 * and returns 0, or -1 when the nesting was not closed or a write failed.
 */
#ifndef STC_CLI_JSON_H
#define STC_CLI_JSON_H

#include <stdint.h>
#include <stdio.h>

#define CLI_JSON_DEPTH 16

typedef struct cli_json {
    FILE *f;
    int   depth;                      /* open objects / arrays */
    int   count[CLI_JSON_DEPTH + 1];  /* values written at each level (for the commas) */
    char  closer[CLI_JSON_DEPTH + 1]; /* '}' or ']' of each open level */
    int   bad;                        /* nesting misuse */
} cli_json;

void cli_json_begin(cli_json *j, FILE *f);
void cli_json_object(cli_json *j, const char *key);   /* opens {  */
void cli_json_array(cli_json *j, const char *key);    /* opens [  */
void cli_json_close(cli_json *j);                     /* closes the innermost } or ] */
void cli_json_str(cli_json *j, const char *key, const char *v);   /* NULL v = null */
void cli_json_u64(cli_json *j, const char *key, uint64_t v);
void cli_json_i64(cli_json *j, const char *key, int64_t v);
void cli_json_double(cli_json *j, const char *key, double v);
void cli_json_bool(cli_json *j, const char *key, int v);
int  cli_json_end(cli_json *j);

#endif
