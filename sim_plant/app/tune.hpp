#pragma once

namespace pneu::plant_app {

/// `pneu-plant tune`: see its --help.
int tune(int argc, char** argv);

}  // namespace pneu::plant_app
