// <httplib.h> for server/ and client/ (cpp-httplib is the contract's
// transport). glibc's <resolv.h>, which httplib includes, defines the macro
// `_res`, and Eigen (core headers) uses `_res` as a parameter name: include
// httplib through this header only, so the two can share a translation unit.
#pragma once

#include <httplib.h>

#ifdef _res
#undef _res
#endif
