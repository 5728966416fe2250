// Which clock paces the loop (controller.clock).
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::controller {

enum class ClockKind { kSimulated, kReal };

}  // namespace pneu::controller

namespace pneu::config::schema {

using controller::ClockKind;

inline constexpr Choice<ClockKind> kClocks[] = {{"simulated", ClockKind::kSimulated}, {"real", ClockKind::kReal}};

}  // namespace pneu::config::schema
