// The 4-lane contact and pin paths built for AVX-512F and VL (x86-64; elsewhere for the
// baseline, never chosen there). The operations are contact_kernel_x4.cpp's, on the same 4-double
// vectors; AVX-512VL gives them 32 vector registers instead of 16, so a block's lanes spill far
// less. Never -mfma, as for the AVX2 build.
#define FULCRUM_X4_NAME(base) base##_x4e
#include "contact_kernel_x4.cpp"
