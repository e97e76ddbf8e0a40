#pragma once
/// @file
/// A number as a user reads it in a message: "%.6g" (six significant
/// digits, exponent form for very large or small magnitudes, "inf", "nan").
/// std::to_string prints "%f", i.e. 309 digits for 1e308 and "0.000000" for
/// 1e-300.

#include <string>

namespace frictiond {

std::string NumberText(double x);

}  // namespace frictiond
