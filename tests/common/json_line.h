/* tests/common/json_line.h - one line of JSON parsed strictly with json-c (Debian
 * libjson-c-dev), for the tests of seamtexd's JSON log lines.
 *
 * Owns: the strict parse (RFC 8259 only, input validated as UTF-8, nothing after the value)
 * and field getters that fail the calling cmocka test when a field is missing or of another
 * type. Binaries that use it link -ljson-c (tests/module.mk).
 */
#ifndef ST_JSON_LINE_H
#define ST_JSON_LINE_H

#include <stddef.h>
#include <stdint.h>

#include <json-c/json.h>

/* Parses s[0..len) as exactly one JSON object; NULL (with the reason on stderr) otherwise.
 * The caller releases it with json_object_put. */
struct json_object *st_json_line(const char *s, size_t len);

/* The string field `key` of o, or NULL when absent or not a string. Borrowed from o. */
const char *st_json_str(struct json_object *o, const char *key);

/* The integer field `key` of o; -1 when absent or not an integer. */
int64_t st_json_int(struct json_object *o, const char *key);

#endif
