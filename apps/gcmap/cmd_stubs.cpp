#include "commands.hpp"
namespace gcmap::cli {
void add_map(CLI::App&, Runner&) {}
void add_demo(CLI::App&, Runner&) {}
void add_config(CLI::App&, Runner&) {}
}
