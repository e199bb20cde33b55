// gtest: the agent's model loader fed seeded random mutations of a model (issue 15): it either
// loads or throws ModelError, never another exception or a crash, and what it loads is sound.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "anyscale_agent_cpp/node_model.h"

using namespace anyscale_agent;
namespace fs = std::filesystem;

namespace
{
std::string readFile(const fs::path& p)
{
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The rostests' model: every launch feature the agent reads (args, remaps, params, $(find)).
const fs::path kSeedModel = fs::path(__FILE__).parent_path() / "config" / "test_model.yaml";

// One mutation: bytes flipped, YAML syntax inserted, a line dropped or repeated, or the end cut.
std::string mutate(std::string text, std::mt19937& rng)
{
  static const std::string kSyntax = "{}[]:,&*!|>'\"-#%@`\n \t\\$()";
  auto pos = [&] {
    return std::uniform_int_distribution<std::size_t>(0, text.empty() ? 0 : text.size() - 1)(rng);
  };
  const int edits = std::uniform_int_distribution<int>(1, 4)(rng);
  for (int i = 0; i < edits && !text.empty(); ++i)
    switch (std::uniform_int_distribution<int>(0, 4)(rng))
    {
      case 0: text[pos()] = char(std::uniform_int_distribution<int>(0, 255)(rng)); break;
      case 1:
        text.insert(
            pos(), 1,
            kSyntax[std::uniform_int_distribution<std::size_t>(0, kSyntax.size() - 1)(rng)]);
        break;
      case 2:
      {
        const auto a = text.rfind('\n', pos());
        const auto b = text.find('\n', a == std::string::npos ? 0 : a + 1);
        if (a != std::string::npos && b != std::string::npos)
          text.erase(a, b - a);
        break;
      }
      case 3:
      {
        const auto a = text.rfind('\n', pos());
        const auto b = text.find('\n', a == std::string::npos ? 0 : a + 1);
        if (a != std::string::npos && b != std::string::npos)
          text.insert(b, text.substr(a, b - a));
        break;
      }
      default: text.resize(pos());
    }
  return text;
}

std::string locate(const std::string& pkg)
{
  return pkg == "anyscale_agent_cpp" ? "/opt/anyscale_agent_cpp" : "";
}
}  // namespace

TEST(NodeModelFuzz, MutatedModelsLoadOrFailWithModelErrorOnly)
{
  const std::string seed = readFile(kSeedModel);
  ASSERT_FALSE(seed.empty()) << kSeedModel;
  const fs::path file =
      fs::temp_directory_path() / ("anyscale_model_fuzz_" + std::to_string(::getpid()) + ".yaml");
  std::mt19937 rng(15);  // seeded: a failure is reproducible
  int loaded = 0, refused = 0;
  for (int i = 0; i < 2000; ++i)
  {
    const std::string text = mutate(seed, rng);
    std::ofstream(file, std::ios::binary | std::ios::trunc) << text;
    try
    {
      const NodeModel m = NodeModel::load(file.string());
      ++loaded;
      for (const auto& name : m.names())
      {
        const NodeDecl* d = m.find(name);
        ASSERT_NE(d, nullptr);
        EXPECT_TRUE(isValidNodeName(d->name) && isValidPackageName(d->package) &&
                    isValidExecutableName(d->type))
            << "mutation " << i << " loaded a node the allow-list should refuse:\n"
            << text;
        for (const auto& kv : d->params)
          EXPECT_TRUE(kv.first.IsScalar()) << "mutation " << i << ":\n" << text;
        try
        {
          buildArgv(*d, "/opt/exe", locate, "__laptop");
        }
        catch (const ModelError&)
        {}
      }
    }
    catch (const ModelError& e)
    {
      ++refused;
      EXPECT_EQ(std::string(e.what()).rfind(file.string(), 0), 0u)
          << "error does not name the file: " << e.what();
    }
    catch (const std::exception& e)
    {
      ADD_FAILURE() << "mutation " << i << " threw " << typeid(e).name() << ": " << e.what() << "\n"
                    << text;
    }
  }
  fs::remove(file);
  EXPECT_GT(loaded, 0);
  EXPECT_GT(refused, 0);
}

TEST(NodeModelFuzz, ParamsKeyThatIsNotANameIsRefusedAtLoad)
{
  const auto root =
      YAML::Load("nodes: [{name: a, launch: {package: p, type: t, params: {[1, 2]: x}}}]");
  EXPECT_THROW(NodeModel::parse(root, "m.yaml"), ModelError);
  const auto slash =
      YAML::Load("nodes: [{name: a, launch: {package: p, type: t, params: {/abs: 1}}}]");
  EXPECT_THROW(NodeModel::parse(slash, "m.yaml"), ModelError);
}
