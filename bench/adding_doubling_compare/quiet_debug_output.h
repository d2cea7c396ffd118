/* Forced into iad's ad_start.c only (CMakeLists.txt): at commit cb479c4d its Choose_Cone_Method prints every
   quadrature angle to stderr on every oblique solve, a leftover of debugging that would dominate the timing. This
   silences all of that file's fprintf output, its one error message (a negative cone angle, which these inputs
   never give) included. */
#include <stdio.h>
#define fprintf(...) 0
