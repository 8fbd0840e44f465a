/// \file cmd_security.cpp
/// `stroma security init DIR`: a test PKI and signed DDS Security documents for a protected
/// domain (dds/dds_security.hpp; SECURITY.md).

#include <algorithm>

#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "dds/dds_security.hpp"

namespace stroma::cli {

void add_security(CLI::App& app, std::vector<Command>& out) {
  CLI::App* sec = app.add_subcommand("security", "DDS Security for a protected domain (SECURITY.md)");
  sec->require_subcommand(1);
  CLI::App* init = sec->add_subcommand(
      "init",
      "Create a test identity CA and permissions CA, identities for the server, the renderer and each tool "
      "client, and signed governance and permissions documents (with openssl) in a new directory; then run "
      "serve, tool and render with --security DIR");
  auto opt = std::make_shared<SecurityInitOptions>();
  auto clients = std::make_shared<std::vector<std::string>>();
  init->add_option("dir", opt->dir, "Directory to create (must not exist)")->required();
  init->add_option("--client", *clients,
                   "A tool client identity and the tools it may command: NAME=TOOL[,TOOL...] (repeatable; "
                   "default: tool=probe)");
  auto operators = std::make_shared<std::vector<std::string>>();
  init->add_option("--operator", *operators,
                   "A client (named by --client) that may also write stroma_Control: pause, step, reset, stop "
                   "(repeatable; default: none when --client is given, the default client otherwise)");
  init->add_option("--days", opt->days, "Validity of the certificates")->capture_default_str()->check(CLI::PositiveNumber);
  out.push_back({init, [opt, clients, operators]() {
                   if (!clients->empty()) {
                     opt->clients.clear();
                     for (const std::string& c : *clients) {
                       const auto eq = c.find('=');
                       if (eq == std::string::npos || eq == 0 || eq + 1 == c.size())
                         throw std::runtime_error("--client '" + c + "': expected NAME=TOOL[,TOOL...]");
                       SecurityClient sc;
                       sc.name = c.substr(0, eq);
                       std::string rest = c.substr(eq + 1);
                       for (size_t b = 0; b <= rest.size();) {
                         const size_t e = rest.find(',', b);
                         const std::string t = rest.substr(b, e == std::string::npos ? std::string::npos : e - b);
                         if (!t.empty()) sc.tools.push_back(t);
                         if (e == std::string::npos) break;
                         b = e + 1;
                       }
                       opt->clients.push_back(sc);
                     }
                   }
                   for (const std::string& name : *operators) {
                     auto it = std::find_if(opt->clients.begin(), opt->clients.end(),
                                            [&](const SecurityClient& c) { return c.name == name; });
                     if (it == opt->clients.end())
                       throw std::runtime_error("--operator '" + name + "': no such client (name it with --client)");
                     it->control = true;
                   }
                   spdlog::info("security init: creating {} (RSA 2048 keys, {} days)", opt->dir, opt->days);
                   init_security_dir(*opt);
                   std::string who;
                   for (const SecurityClient& c : opt->clients) {
                     who += (who.empty() ? "" : "; ") + c.name + ": ";
                     for (size_t i = 0; i < c.tools.size(); ++i) who += (i ? "," : "") + c.tools[i];
                     if (c.control) who += " (operator)";
                   }
                   spdlog::info("security init: done. Identities: server, renderer, and clients ({}). Run: stroma serve "
                                "SCENARIO --security {} & stroma tool --security {} --identity NAME --name TOOL",
                                who, opt->dir, opt->dir);
                   return 0;
                 }});
}

}  // namespace stroma::cli
