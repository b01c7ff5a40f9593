/* util/loadpath.h - STU_LOADPATH: marks a function on the path of loading a file into a set
 * (the Ptex reader, the set's creation, the file read and its buffers).
 *
 * Why: in a fresh process every 64 KiB window of code run for the first time costs a page
 * fault (about 10 us on the project's VM, where a whole small .ptx import is 150-300 us), and
 * the linker scatters these functions over the binary by archive member (a daemon's or
 * bench_ptex's first import ran code in 3-4 windows megabytes apart). Marked hot, GCC puts
 * them in .text.hot, which the default GNU ld script places together at the start of .text.
 * The mark changes placement (and lets GCC optimise them for speed, as -O2 already does);
 * behaviour is the same. Compilers without the attribute ignore it.
 */
#ifndef STU_LOADPATH_H
#define STU_LOADPATH_H

#if defined(__GNUC__)
#define STU_LOADPATH __attribute__((hot))
#else
#define STU_LOADPATH
#endif

#endif
