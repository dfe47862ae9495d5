// Included first by every spd/*.cpp: forbids fusing a*b+c into one FMA.
// The generators reproduce Haines' original output byte for byte, which
// depends on every product being rounded before it is added, as the x86-64
// baseline the originals were built for does. GCC contracts by default when
// FMA is available (-march=x86-64-v3 or native), and clang within expressions.
#pragma once

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif
