/*
 * rel_measured: the one line a reliability test prints per measured case,
 *
 *   measured: NAME key=value key=value ...
 *
 * (values without spaces).  tests/reliability/rel_doc.py runs the tests,
 * collects these lines and writes the tables of docs/results/reliability.md from
 * them, so no measured number is typed into the documentation.
 * Header-only host test code.
 */
#ifndef REL_MEASURED_H
#define REL_MEASURED_H

#include <stdarg.h>
#include <stdio.h>

__attribute__((format(printf, 2, 3))) static inline void rel_measured(const char *name,
                                                                      const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    printf("measured: %s ", name);
    vprintf(fmt, ap);
    printf("\n");
    fflush(stdout);
    va_end(ap);
}

/* A bound's literal as text, for a measured: line that prints exactly the
 * number the assertion uses (printf cannot give "1e-3" back from the
 * double):  #define X_BOUND 1e-3 ... "bound=" BOUND_TEXT(X_BOUND) */
#define BOUND_TEXT_(x) #x
#define BOUND_TEXT(x) BOUND_TEXT_(x)

#endif /* REL_MEASURED_H */
