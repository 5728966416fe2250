#pragma once

namespace pneu::plant_app {

extern const char* const kServeHelpText;
/// `pneu-plant serve`: see its --help.
int serve(int argc, char** argv);

}  // namespace pneu::plant_app
