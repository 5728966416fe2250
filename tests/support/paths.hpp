// Test support: where the tests find the programs this build made and the configuration files the
// project ships (the test target defines PNEU_BINARY_DIR and PNEU_SOURCE_DIR).
#pragma once

#include <string>

namespace pneu::test {

#ifdef PNEU_BINARY_DIR
/// A program of this build: build/bin/`name`.
inline std::string bin(const std::string& name) { return std::string(PNEU_BINARY_DIR) + "/bin/" + name; }
#endif

#ifdef PNEU_SOURCE_DIR
/// A shipped configuration file: config/`file`.
inline std::string shipped_config(const std::string& file) { return std::string(PNEU_SOURCE_DIR) + "/config/" + file; }
/// The shipped configuration of the hardware-in-the-loop bench (pneu-plant serve over Modbus).
inline std::string hil_yaml() { return shipped_config("hil.yaml"); }
#endif

}  // namespace pneu::test
