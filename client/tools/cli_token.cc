// `friction token create|list|revoke` (API tokens) and `friction audit`
// (the audit log); both need an operator token (docs/auth.md).
#include <iostream>

#include "frictiond/client/client.h"

#include "cli.h"

namespace frictiond::cli {

namespace {

std::string UrlPart(const std::string& s) { return UrlEncode(s); }

}  // namespace

void RegisterTokenCommands(CLI::App& app, Globals& g) {
  auto* token = app.add_subcommand(
      "token", "API tokens (needs an operator token): create, list, revoke");
  token->require_subcommand(1);
  {
    auto* cmd = token->add_subcommand(
        "create", "create a token; prints its secret (shown only once)");
    static std::string name, role;
    static bool json_out = false;
    cmd->add_option("--name", name, "label of the token")->required();
    cmd->add_option("--role", role, "reader, robot or operator")
        ->required()
        ->check(CLI::IsMember({"reader", "robot", "operator"}));
    cmd->add_flag("--json", json_out, "print the whole reply as JSON");
    cmd->callback([&g] {
      RunCommand([&] {
        const nlohmann::json body = {{"name", name}, {"role", role}};
        const nlohmann::json r =
            MakeClient(g).SendJson("POST", "/v1/tokens", body.dump());
        if (json_out) {
          std::cout << r.dump(2) << "\n";
          return;
        }
        std::cerr << "created token " << r.value("id", "") << " (" << role
                  << "); its secret is shown only now:\n";
        std::cout << r.value("secret", "") << "\n";
      });
    });
  }
  {
    auto* cmd = token->add_subcommand("list", "list tokens (no secrets)");
    static bool json_out = false;
    cmd->add_flag("--json", json_out, "print JSON");
    cmd->callback([&g] {
      RunCommand([&] {
        const nlohmann::json r = MakeClient(g).GetJson("/v1/tokens");
        if (json_out) {
          std::cout << r.dump(2) << "\n";
          return;
        }
        for (const auto& t : r["tokens"]) {
          std::cout << t.value("id", "") << "\t" << t.value("role", "") << "\t"
                    << (t.value("revoked", false) ? "revoked" : "active")
                    << "\t" << t.value("created_at", "") << "\t"
                    << t.value("name", "") << "\n";
        }
      });
    });
  }
  {
    auto* cmd = token->add_subcommand("revoke", "revoke a token by id");
    static std::string id;
    cmd->add_option("ID", id, "token id (tok_...)")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        MakeClient(g).SendJson("DELETE", "/v1/tokens/" + UrlPart(id), "");
        std::cout << "revoked " << id << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "audit", "the audit log: who changed what, when, from where");
    static std::string material;
    static long long after = 0;
    static int limit = 100;
    cmd->add_option("--material", material, "only this material's entries");
    cmd->add_option("--after", after, "entries after this id")
        ->capture_default_str();
    cmd->add_option("--limit", limit, "at most this many entries")
        ->capture_default_str();
    cmd->callback([&g] {
      RunCommand([&] {
        std::string path = "/v1/audit?after=" + std::to_string(after) +
                           "&limit=" + std::to_string(limit);
        if (!material.empty()) path += "&material=" + UrlPart(material);
        std::cout << MakeClient(g).GetJson(path).dump(2) << "\n";
      });
    });
  }
}

}  // namespace frictiond::cli
