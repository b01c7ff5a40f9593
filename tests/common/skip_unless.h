/* tests/common/skip_unless.h - the one "skip this test on this machine" of the tests.
 *
 * Owns: ST_SKIP_UNLESS(have, why), which ends a cmocka test as skipped, with a line saying
 * why, when have is false (a CPU feature a path needs), and ST_SKIP_WITHOUT_AVX2() for the
 * Ptex filters' AVX2 paths (pf_have_avx2: AVX2 + FMA + F16C). Macros: they need cmocka's
 * skip() and print_message at the test's own site. Does not own: the paths or their checks.
 */
#ifndef ST_SKIP_UNLESS_H
#define ST_SKIP_UNLESS_H

#define ST_SKIP_UNLESS(have, why)                                                            \
    do {                                                                                     \
        if (!(have)) {                                                                       \
            print_message("%s\n", (why));                                                    \
            skip();                                                                          \
        }                                                                                    \
    } while (0)

#define ST_SKIP_WITHOUT_AVX2() ST_SKIP_UNLESS(pf_have_avx2(), "no AVX2 + FMA + F16C: skipped")

#endif
