/* Strict parsing of the replay and loop programs' input: one line holds exactly `count`
 * finite numbers separated by commas (spaces and tabs allowed around them) and nothing
 * else; a line longer than MHE_LINE_MAX - 2 bytes (8191 without its newline) is refused,
 * not split. Every refusal names the line (1-based) on stderr. */
#ifndef MHE_PARSE_H
#define MHE_PARSE_H
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MHE_LINE_MAX 8193

/* Reads line `lineno` into buf (MHE_LINE_MAX bytes): 1 when read, 0 at the end of the input,
 * -1 (message on stderr) when it is too long or the input cannot be read. */
static int mhe_read_line(const char *prog, char *buf, long lineno) {
    size_t len;
    if (!fgets(buf, MHE_LINE_MAX, stdin)) {
        if (ferror(stdin)) {
            fprintf(stderr, "%s: line %ld: cannot read the input\n", prog, lineno);
            return -1;
        }
        return 0;
    }
    len = strlen(buf);
    if ((len > 0 && buf[len - 1] == '\n') || feof(stdin)) return 1;
    fprintf(stderr, "%s: line %ld: longer than %d bytes\n", prog, lineno, MHE_LINE_MAX - 2);
    return -1;
}

/* 1 if the line holds only blanks (skipped). */
static int mhe_blank(const char *p) {
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') p++;
    return *p == '\0';
}

/* Parses exactly `count` finite numbers into out; 0, or -1 with a message naming the line
 * and `what` (e.g. "u then y"). */
static int mhe_parse_line(const char *prog, const char *line, long lineno, int count,
                          const char *what, double *out) {
    const char *p = line;
    char *end;
    int i;
    for (i = 0; i < count; i++) {
        while (*p == ' ' || *p == '\t') p++;
        if (i > 0) {
            if (*p != ',') goto bad;
            p++;
            while (*p == ' ' || *p == '\t') p++;
        }
        if (*p == '\0' || *p == '\n' || *p == '\r') goto bad;
        out[i] = strtod(p, &end);
        if (end == p || !isfinite(out[i])) goto bad;
        p = end;
    }
    if (!mhe_blank(p)) goto bad;
    return 0;
bad:
    fprintf(stderr, "%s: line %ld: expected exactly %d finite numbers (%s), comma-separated\n",
            prog, lineno, count, what);
    return -1;
}
#endif
