// `pneu-plant serve` in a build without libmodbus (PNEU_WITH_MODBUS=OFF): refused, saying why.
#include "serve.hpp"

#include "pneu/config/cli.hpp"

namespace pneu::plant_app {

int serve(int, char**) {
  throw cli::UsageError(
      "serve: this pneu-plant was built without libmodbus (PNEU_WITH_MODBUS=OFF), which serve needs; "
      "rebuild with it (Debian: libmodbus-dev)");
}

}  // namespace pneu::plant_app
