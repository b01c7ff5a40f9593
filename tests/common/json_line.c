/* tests/common/json_line.c - strict one-line JSON parsing for tests (json_line.h). */
#include "json_line.h"

#include <stdio.h>

struct json_object *st_json_line(const char *s, size_t len)
{
    struct json_tokener *tok = json_tokener_new();
    if (!tok)
        return NULL;
    json_tokener_set_flags(tok, JSON_TOKENER_STRICT | JSON_TOKENER_VALIDATE_UTF8);
    struct json_object *o = json_tokener_parse_ex(tok, s, (int)len);
    enum json_tokener_error e = json_tokener_get_error(tok);
    size_t end = json_tokener_get_parse_end(tok);
    json_tokener_free(tok);
    if (!o || e != json_tokener_success || end != len ||
        !json_object_is_type(o, json_type_object)) {
        fprintf(stderr, "not one JSON object (%s, parsed %zu of %zu bytes): %.*s\n",
                json_tokener_error_desc(e), end, len, (int)len, s);
        json_object_put(o);
        return NULL;
    }
    return o;
}

const char *st_json_str(struct json_object *o, const char *key)
{
    struct json_object *v;
    if (!json_object_object_get_ex(o, key, &v) || !json_object_is_type(v, json_type_string))
        return NULL;
    return json_object_get_string(v);
}

int64_t st_json_int(struct json_object *o, const char *key)
{
    struct json_object *v;
    if (!json_object_object_get_ex(o, key, &v) || !json_object_is_type(v, json_type_int))
        return -1;
    return json_object_get_int64(v);
}
