/* host_text.h - the text helpers both plain C test hosts (c_host.c, native_c_host.c) use to
 * read an unzipped FMU's modelDescription.xml. C99, header-only (static functions). */
#ifndef HOST_TEXT_H
#define HOST_TEXT_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the whole file as a NUL-terminated string (free it), or NULL */
static char *read_file(const char *path) {
    FILE *f = fopen(path, "rb");
    long n;
    char *buf;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    fseek(f, 0, SEEK_SET);
    buf = malloc((size_t)n + 1);
    if (!buf || fread(buf, 1, (size_t)n, f) != (size_t)n) {
        fclose(f);
        free(buf);
        return NULL;
    }
    buf[n] = 0;
    fclose(f);
    return buf;
}

/* value of attribute NAME="..." inside the tag that starts at TAG (up to its '>') */
static int attr(const char *tag, const char *name, char *out, size_t size) {
    const char *end = strchr(tag, '>');
    char key[64];
    const char *p, *q;
    size_t n;
    snprintf(key, sizeof key, " %s=\"", name);
    p = strstr(tag, key);
    if (!p || (end && p > end)) return 0;
    p += strlen(key);
    q = strchr(p, '"');
    n = (size_t)(q - p) < size - 1 ? (size_t)(q - p) : size - 1;
    memcpy(out, p, n);
    out[n] = 0;
    return 1;
}

#endif
