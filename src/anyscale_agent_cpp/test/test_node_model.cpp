// gtest: model allow-list parsing, name checks, $(find) and rosrun-style executable lookup.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "anyscale_agent_cpp/node_model.h"

using namespace anyscale_agent;
namespace fs = std::filesystem;

namespace
{
const char* kModel = R"(
scales: [{name: robot, master: true}]
nodes:
  - name: amcl
    launch:
      package: nav_pkg
      type: amcl_node
      args: [--flag, $(find nav_pkg)/cfg.yaml]
      remaps: {scan: /base_scan}
      params: {map_file: $(find nav_pkg)/maps/m.yaml, particles: 500, nested: {a: [1, 2]}}
    cpu_usage: {robot: 50}
  - name: robot/camera
    launch: {package: drivers, type: camera.py, warm_start: true, nice: 5}
)";

std::string locate(const std::string& pkg)
{
  return pkg == "nav_pkg" ? "/opt/nav_pkg" : "";
}

void touchExecutable(const fs::path& p)
{
  fs::create_directories(p.parent_path());
  std::ofstream(p) << "#!/bin/sh\n";
  ::chmod(p.c_str(), 0755);
}
}  // namespace

TEST(NodeModel, ParsesDeclaredNodes)
{
  const auto m = NodeModel::parse(YAML::Load(kModel), "test.yaml");
  EXPECT_EQ(m.names(), (std::vector<std::string>{"amcl", "robot/camera"}));
  const NodeDecl* d = m.find("/amcl");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d, m.find("amcl"));
  EXPECT_EQ(d->package, "nav_pkg");
  EXPECT_EQ(d->params["particles"].as<int>(), 500);
  EXPECT_FALSE(d->warm_start);
  EXPECT_TRUE(m.find("robot/camera")->warm_start);
  EXPECT_EQ(m.find("robot/camera")->nice, 5);
  EXPECT_EQ(d->nice, 0);
  EXPECT_EQ(m.find("teleop"), nullptr);
}

TEST(NodeModel, AScalesMemoryIsTheModels)
{
  std::string text = kModel;
  text.replace(text.find("scales: [{name: robot, master: true}]"), 37,
               "scales: [{name: robot, master: true, memory_mb: 2048},\n"
               "         {name: laptop, cpu_ghz: 2.8, cores: 4, memory_mb: 4096.5, alpha: 3.5}]");
  const auto m = NodeModel::parse(YAML::Load(text), "test.yaml");
  EXPECT_EQ(m.scaleMemoryMb("laptop"), 4096.5);
  EXPECT_EQ(m.scaleMemoryMb("server"), std::nullopt);
  EXPECT_EQ(NodeModel::parse(YAML::Load(kModel), "test.yaml").scaleMemoryMb("robot"), std::nullopt);
}

TEST(NodeModel, AnOutputsToleranceIsTheSmallestOfItsConnections)
{
  const auto m = NodeModel::parse(YAML::Load(std::string(kModel) + R"(
connections:
  - {publisher: amcl, subscriber: ekf, topic: /amcl_pose, tolerance: 2}
  - {publisher: amcl, subscriber: nav, topic: /amcl_pose, tolerance: 0.5}
  - {publisher: amcl, subscriber: viz, topic: /amcl_pose, tolerance: 0}
  - {publisher: robot/camera, subscriber: ar, topic: /image}
  - {publisher: not_declared, subscriber: ar, topic: /x, tolerance: 1}
)"),
                                  "test.yaml");
  EXPECT_DOUBLE_EQ(m.find("amcl")->output_tolerance_s, 0.5);  // 0: no tolerance, not the smallest
  EXPECT_DOUBLE_EQ(m.find("robot/camera")->output_tolerance_s, 0.0);
  EXPECT_DOUBLE_EQ(
      NodeModel::parse(YAML::Load(kModel), "test.yaml").find("amcl")->output_tolerance_s, 0.0);
}

TEST(NodeModel, PauseHandOffAndSubscriptionsAreTheModels)
{
  const auto m = NodeModel::parse(YAML::Load(std::string(kModel) + R"(
  - name: ar
    launch: {package: ar_pkg, type: ar, pause_at_home: true}
    state_handoff: {kind: pose, topic: /ar_pose}
connections:
  - {publisher: robot/camera, subscriber: ar, topic: /image}
  - {publisher: ar, subscriber: amcl, topic: ar_markers}
)"),
                                  "test.yaml");
  EXPECT_TRUE(m.find("ar")->pause_at_home);
  EXPECT_FALSE(m.find("amcl")->pause_at_home);
  EXPECT_EQ(m.find("ar")->handoff_keys, handoffKeys("pose"));
  EXPECT_EQ(m.find("ar")->handoff_keys.count("initial_pose_x"), 1u);
  EXPECT_TRUE(m.find("amcl")->handoff_keys.empty());
  EXPECT_TRUE(m.subscribes("/ar", "/image"));
  EXPECT_TRUE(m.subscribes("amcl", "/ar_markers"));  // a relative topic of the model is global
  EXPECT_FALSE(m.subscribes("/amcl", "/image"));
  EXPECT_FALSE(m.subscribes("/camera_driver", "/image"));
  for (const auto& [bad, words] : std::vector<std::pair<std::string, std::string>>{
           {"launch: {package: p, type: t, pause_at_home: yes}",
            "pause_at_home must be true or false"},
           {"launch: {package: p, type: t}\n    state_handoff: {kind: memory}", "not one of: pose"},
           {"launch: {package: p, type: t}\n    state_handoff: pose",
            "state_handoff must be a map"}})
  {
    const std::string text = "nodes:\n  - name: x\n    " + bad + "\n";
    try
    {
      NodeModel::parse(YAML::Load(text), "bad.yaml");
      ADD_FAILURE() << "accepted: " << bad;
    }
    catch (const ModelError& e)
    {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.yaml: node 'x'"), std::string::npos) << e.what();
    }
  }
}

TEST(NodeModel, AnAliasBombOrANullInLaunchParamsIsRefusedAtLoad)
{
  // 9 aliases of 9, eight times over: 9^9 values behind a dozen lines, which the agent
  // converted into parameters at every start of the node.
  std::string bomb = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i <= 8; ++i)
  {
    const std::string prev = "*a" + std::to_string(i - 1);
    bomb += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [" + prev;
    for (int j = 1; j < 9; ++j)
      bomb += ", " + prev;
    bomb += "]\n";
  }
  const std::string bombed =
      bomb + "nodes: [{name: x, launch: {package: p, type: t, params: {b: *a8}}}]\n";
  for (const auto& [text, words] : std::vector<std::pair<std::string, std::string>>{
           {bombed, "more than 10000 values"},
           {"nodes: [{name: x, launch: {package: p, type: t, params: {n: ~}}}]", "null value"},
           {"nodes: [{name: x, launch: {package: p, type: t, params: {n: {m: [1, ~]}}}}]",
            "param 'n'.m[1]: a null value"}})
  {
    try
    {
      NodeModel::parse(YAML::Load(text), "bad.yaml");
      ADD_FAILURE() << "accepted: " << words;
    }
    catch (const ModelError& e)
    {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(NodeModel::parse(YAML::Load(kModel), "test.yaml"));
}

TEST(NodeModel, ArgvHasArgsRemapsAndName)
{
  const auto m = NodeModel::parse(YAML::Load(kModel), "test.yaml");
  const auto argv = buildArgv(*m.find("amcl"), "/x/amcl_node", locate);
  EXPECT_EQ(argv, (std::vector<std::string>{"/x/amcl_node", "--flag", "/opt/nav_pkg/cfg.yaml",
                                            "scan:=/base_scan", "__name:=amcl"}));
  const auto cam = buildArgv(*m.find("robot/camera"), "/y/camera.py", locate);
  EXPECT_EQ(cam, (std::vector<std::string>{"/y/camera.py", "__ns:=/robot", "__name:=camera"}));
}

TEST(NodeModel, InstancesOnRemoteScalesRunUnderTheirScalesName)
{
  EXPECT_EQ(instanceName("/amcl", "robot", true), "/amcl");
  EXPECT_EQ(instanceName("/amcl", "laptop", false), "/amcl__laptop");
  EXPECT_EQ(instanceName("ns/amcl", "server", false), "ns/amcl__server");
  EXPECT_NE(instanceName("/amcl", "laptop", false), instanceName("/amcl", "server", false));
  const auto m = NodeModel::parse(YAML::Load(kModel), "test.yaml");
  const auto argv =
      buildArgv(*m.find("robot/camera"), "/y/camera.py", locate, instanceSuffix("laptop", false));
  EXPECT_EQ(argv,
            (std::vector<std::string>{"/y/camera.py", "__ns:=/robot", "__name:=camera__laptop"}));
}

TEST(NodeModel, AQualifiedNameHasOneLeadingSlash)
{
  EXPECT_EQ(qualifiedName("relay"), "/relay");
  EXPECT_EQ(qualifiedName("/relay"), "/relay");
  EXPECT_EQ(qualifiedName("robot/camera"), "/robot/camera");
  EXPECT_EQ(qualifiedName(""), "/");
}

TEST(NodeModel, DoubleUnderscoreIsReservedForInstanceNames)
{
  const char* yaml = "nodes: [{name: amcl__laptop, launch: {package: p, type: t}}]";
  try
  {
    NodeModel::parse(YAML::Load(yaml), "m.yaml");
    FAIL() << "a declared name could collide with an instance name";
  }
  catch (const ModelError& e)
  {
    EXPECT_NE(std::string(e.what()).find("reserved for instance names"), std::string::npos)
        << e.what();
  }
}

TEST(NodeModel, ErrorsNameTheNodeAndKey)
{
  auto error_of = [](const std::string& yaml) {
    try
    {
      NodeModel::parse(YAML::Load(yaml), "m.yaml");
    }
    catch (const ModelError& e)
    {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("scales: []").find("'nodes' list"), std::string::npos);
  EXPECT_NE(error_of("nodes: [{launch: {package: p, type: t}}]").find("missing key 'name'"),
            std::string::npos);
  EXPECT_NE(error_of("nodes: [{name: a}]").find("node 'a': missing map 'launch'"),
            std::string::npos);
  EXPECT_NE(
      error_of("nodes: [{name: a, launch: {package: p, type: ../../bin/sh}}]").find("launch.type"),
      std::string::npos);
  EXPECT_NE(error_of("nodes: [{name: a, launch: {package: p, type: /bin/sh}}]").find("launch.type"),
            std::string::npos);
  EXPECT_NE(error_of("nodes: [{name: '/a', launch: {package: p, type: t}}]")
                .find("not a valid ROS node name"),
            std::string::npos);
  EXPECT_NE(error_of("nodes: [{name: 'a b', launch: {package: p, type: t}}]").find("not a valid"),
            std::string::npos);
  EXPECT_NE(
      error_of("nodes: [{name: a, launch: {package: 'p;rm', type: t}}]").find("launch.package"),
      std::string::npos);
  EXPECT_NE(error_of("nodes: [{name: a, launch: {package: p, type: t}}, {name: a, launch: "
                     "{package: p, type: t}}]")
                .find("declared twice"),
            std::string::npos);
  EXPECT_NE(
      error_of("nodes: [{name: a, launch: {package: p, type: t, args: x}}]").find("launch.args"),
      std::string::npos);
  EXPECT_NE(error_of("nodes: [{name: a, launch: {package: p, type: t, warm_start: yes please}}]")
                .find("launch.warm_start must be true or false"),
            std::string::npos);
  for (const char* bad : {"20", "-21", "2.5", "high"})
    EXPECT_NE(error_of(std::string("nodes: [{name: a, launch: {package: p, type: t, nice: ") + bad +
                       "}}]")
                  .find("launch.nice must be an integer from -20 to 19"),
              std::string::npos)
        << bad;
  const std::string node = "nodes: [{name: a, launch: {package: p, type: t}}]\n";
  EXPECT_NE(error_of(node + "connections: {a: b}").find("'connections' must be a list"),
            std::string::npos);
  EXPECT_NE(error_of(node + "connections: [{subscriber: b}]")
                .find("connections[0]: missing key 'publisher'"),
            std::string::npos);
  for (const char* bad : {"-1", "soon", "[1]", ".nan"})
    EXPECT_NE(
        error_of(node + "connections: [{publisher: a, tolerance: " + bad + "}]")
            .find("connections[0] (publisher 'a'): 'tolerance' must be a number of seconds >= 0"),
        std::string::npos)
        << bad;
  for (const char* bad : {"0", "-5", "lots", ".nan", "[1]"})
    EXPECT_NE(error_of(node + "scales: [{name: laptop, memory_mb: " + bad + "}]")
                  .find("scales[0] (laptop): 'memory_mb' must be a positive number"),
              std::string::npos)
        << bad;
  EXPECT_NE(error_of(node + "scales: {laptop: 1}").find("'scales' must be a list"),
            std::string::npos);
  try
  {
    NodeModel::load("/nonexistent/model.yaml");
    FAIL();
  }
  catch (const ModelError& e)
  {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/model.yaml"), std::string::npos);
  }
}

TEST(NodeModel, NameChecks)
{
  EXPECT_TRUE(isValidNodeName("amcl"));
  EXPECT_TRUE(isValidNodeName("ns/amcl_2"));
  EXPECT_FALSE(isValidNodeName("ns//amcl"));
  EXPECT_FALSE(isValidNodeName("2amcl"));
  EXPECT_FALSE(isValidNodeName("amcl;ls"));
  EXPECT_TRUE(isValidExecutableName("talker.py"));
  EXPECT_FALSE(isValidExecutableName(".."));
  EXPECT_FALSE(isValidExecutableName("a/b"));
  EXPECT_FALSE(isValidExecutableName("-rf"));
  EXPECT_FALSE(isValidExecutableName("x..y"));
}

TEST(SubstituteFind, FindOnlyAndUnknownPackagesFail)
{
  EXPECT_EQ(substituteFind("$(find nav_pkg)/a $(find nav_pkg)", locate),
            "/opt/nav_pkg/a /opt/nav_pkg");
  EXPECT_EQ(substituteFind("plain", locate), "plain");
  EXPECT_THROW(substituteFind("$(find ghost)/x", locate), ModelError);
  EXPECT_THROW(substituteFind("$(env HOME)", locate), ModelError);
  EXPECT_THROW(substituteFind("$(find nav_pkg", locate), ModelError);
}

TEST(ResolveExecutable, LibexecFirstThenPackageTree)
{
  const fs::path root =
      fs::temp_directory_path() / ("anyscale_resolve_" + std::to_string(getpid()));
  fs::remove_all(root);
  touchExecutable(root / "prefix1/lib/pkg/built_node");
  touchExecutable(root / "src/pkg/scripts/script_node.py");
  touchExecutable(root / "src/pkg/scripts/twice");
  touchExecutable(root / "src/pkg/other/twice");
  std::ofstream(root / "src/pkg/scripts/not_executable") << "x";
  touchExecutable(root / "src/pkg/.git/hooks/hidden");
  const PackageLocator loc = [&](const std::string& p) {
    return p == "pkg" ? (root / "src/pkg").string() : "";
  };
  const std::vector<std::string> prefixes{(root / "prefix0").string(), (root / "prefix1").string()};

  EXPECT_EQ(resolveExecutable("pkg", "built_node", prefixes, loc),
            (root / "prefix1/lib/pkg/built_node").string());
  EXPECT_EQ(resolveExecutable("pkg", "script_node.py", prefixes, loc),
            (root / "src/pkg/scripts/script_node.py").string());
  EXPECT_THROW(resolveExecutable("pkg", "not_executable", prefixes, loc), ModelError);
  EXPECT_THROW(resolveExecutable("pkg", "hidden", prefixes, loc), ModelError);
  EXPECT_THROW(resolveExecutable("pkg", "twice", prefixes, loc), ModelError);
  EXPECT_THROW(resolveExecutable("ghost", "x", prefixes, loc), ModelError);
  EXPECT_THROW(resolveExecutable("pkg", "../../bin/sh", prefixes, loc), ModelError);
  try
  {
    resolveExecutable("pkg", "missing", prefixes, loc);
  }
  catch (const ModelError& e)
  {
    EXPECT_NE(std::string(e.what()).find("no executable 'missing' in package 'pkg'"),
              std::string::npos)
        << e.what();
  }
  fs::remove_all(root);
}

TEST(CatkinPrefixes, AppendsUsrLikeDebianCatkin)
{
  EXPECT_EQ(catkinPrefixes("/ws/devel:/opt/x"),
            (std::vector<std::string>{"/ws/devel", "/opt/x", "/usr"}));
  EXPECT_EQ(catkinPrefixes(nullptr), (std::vector<std::string>{"/usr"}));
  EXPECT_EQ(catkinPrefixes("/usr:/a"), (std::vector<std::string>{"/usr", "/a"}));
}
