// Tests that must see NaN, kept out of RPYMobility.cpp, which is compiled with finite math
// (plugin/CMakeLists.txt). This file is compiled with strict IEEE arithmetic.

#include "RPYMobility.h"

bool KnotMM::positivePivot(double s) { return s > 0.0; }
