#include "commands.hpp"
namespace gcmap::cli {
void add_simulate(CLI::App&, Runner&) {}
void add_eval(CLI::App&, Runner&) {}
void add_mme(CLI::App&, Runner&) {}
void add_map(CLI::App&, Runner&) {}
void add_demo(CLI::App&, Runner&) {}
void add_config(CLI::App&, Runner&) {}
}
