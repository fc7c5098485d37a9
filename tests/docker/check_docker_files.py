#!/usr/bin/python3
"""Lints docker/Dockerfile, docker/compose.yaml and .dockerignore without a
Docker engine: stages and COPY sources, the tools the images ship against the
CMake targets, the runtime packages against the tools' shared libraries, the
compose services against the Dockerfile and the tools' own --help, then
yamllint and `docker-compose config` where installed.

  check_docker_files.py SOURCE_DIR BIN_DIR
"""
import json
import os
import re
import shlex
import shutil
import subprocess
import sys

import yaml

source, bin_dir = sys.argv[1:3]
dockerfile = os.path.join(source, "docker", "Dockerfile")
compose_file = os.path.join(source, "docker", "compose.yaml")
failures = []

# Packages every debian:12 image already has (apt itself needs them).
BASE_IMAGE_PACKAGES = {"libc6", "libgcc-s1", "libstdc++6"}
# Sanitizer runtimes appear in PHASECAST_SANITIZE builds only; the images never ship those.
SANITIZER_LIB = re.compile(r"^lib(asan|ubsan|tsan|lsan)\.so")


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what)
    return condition


def skip(what):
    print("SKIP:", what)


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, timeout=120, **kw)


# ---- Dockerfile ---------------------------------------------------------------------

def instructions(path):
    """(line, KEYWORD, arguments) with continuation lines joined and comments dropped."""
    out, buf, start = [], "", 0
    with open(path) as f:
        for n, raw in enumerate(f, 1):
            line = raw.strip()
            if line.startswith("#") or (not line and not buf):
                continue  # Docker drops comment lines, also inside continuations
            if not buf:
                start = n
            if line.endswith("\\"):
                buf += line[:-1] + " "
                continue
            buf += line
            keyword, _, args = buf.strip().partition(" ")
            out.append((start, keyword.upper(), args.strip()))
            buf = ""
    return out


def split_flags(args):
    """--flag=value options in front of an instruction's arguments, then the arguments (exec or shell form)."""
    flags, rest = {}, args.strip()
    while m := re.match(r"--([\w-]+)(?:=(\S*))?\s+", rest):
        flags[m.group(1)] = m.group(2) or ""
        rest = rest[m.end():]
    return flags, json.loads(rest) if rest.startswith("[") else shlex.split(rest)


class Stage:
    def __init__(self, name, base):
        self.name, self.base = name, base
        self.workdir = "/"
        self.context_copies = []  # (source relative to the context, destination)
        self.tools = []  # tools copied from the build's bin folder
        self.packages = []  # apt-get install arguments
        self.entrypoint = None
        self.expose = set()
        self.used_as_source = False


def dockerignore_patterns():
    path = os.path.join(source, ".dockerignore")
    if not check(os.path.isfile(path), ".dockerignore: missing (host build folders would enter the context)"):
        return []
    patterns = []
    for line in open(path):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        negate = line.startswith("!")
        pattern = line.lstrip("!").strip("/")
        # Docker's matching: anchored at the context root, * and ? stop at /, ** crosses it.
        rx = ""
        i = 0
        while i < len(pattern):
            if pattern.startswith("**/", i):
                rx, i = rx + "(?:.*/)?", i + 3
            elif pattern.startswith("**", i):
                rx, i = rx + ".*", i + 2
            elif pattern[i] == "*":
                rx, i = rx + "[^/]*", i + 1
            elif pattern[i] == "?":
                rx, i = rx + "[^/]", i + 1
            else:
                rx, i = rx + re.escape(pattern[i]), i + 1
        patterns.append((re.compile(rx + "$"), negate))
    return patterns


def ignored(path, patterns):
    """Whether .dockerignore keeps path (relative to the context) out of the build context."""
    parts = path.strip("/").split("/")
    result = False
    for rx, negate in patterns:  # the last matching pattern wins; a matched folder takes its contents
        if any(rx.match("/".join(parts[:k])) for k in range(1, len(parts) + 1)):
            result = not negate
    return result


def cmake_tools():
    """add_executable targets outside tests/ and bench/: the project's tools."""
    tools = set()
    for root, dirs, files in os.walk(source):
        rel = os.path.relpath(root, source)
        if rel.split(os.sep)[0] in ("tests", "bench", ".git") or rel.startswith("build"):
            dirs[:] = []
            continue
        if "CMakeLists.txt" in files:
            text = open(os.path.join(root, "CMakeLists.txt")).read()
            tools.update(re.findall(r"add_executable\(\s*([\w-]+)", text))
    return tools


def parse_dockerfile():
    stages, order = {}, []
    current = None
    for line, keyword, args in instructions(dockerfile):
        where = f"Dockerfile:{line}"
        if keyword == "FROM":
            m = re.match(r"(?:--\S+\s+)*(\S+)(?:\s+AS\s+(\S+))?$", args, re.IGNORECASE)
            if not check(m, f"{where}: cannot read FROM {args!r}"):
                continue
            base, name = m.group(1), m.group(2) or str(len(order))
            check(name not in stages, f"{where}: stage name '{name}' used twice")
            if base in stages:
                stages[base].used_as_source = True
            current = stages[name] = Stage(name, base)
            order.append(name)
            continue
        if not check(current is not None, f"{where}: {keyword} before the first FROM"):
            continue
        if keyword == "WORKDIR":
            current.workdir = os.path.normpath(os.path.join(current.workdir, args))
        elif keyword in ("COPY", "ADD"):
            flags, words = split_flags(args)
            if not check(len(words) >= 2, f"{where}: {keyword} needs a source and a destination"):
                continue
            sources, dest = words[:-1], words[-1]
            dest = os.path.normpath(os.path.join(current.workdir, dest)) + ("/" if dest.endswith("/") else "")
            if "from" in flags:
                origin = flags["from"]
                if not check(origin in stages and origin != current.name,
                             f"{where}: COPY --from={origin}: no earlier stage of that name (stages: {order})"):
                    continue
                stages[origin].used_as_source = True
                for s in sources:
                    if "/bin/" in s:  # a built program: it must be one of the project's tools, and built
                        current.tools.append(os.path.basename(s))
            else:
                for s in sources:
                    check(os.path.exists(os.path.join(source, s)), f"{where}: COPY source '{s}' does not exist")
                    check(s in (".", "./") or not ignored(s, ignore_patterns),
                          f"{where}: COPY source '{s}' is excluded by .dockerignore")
                    current.context_copies.append((os.path.normpath(s), dest.rstrip("/")))
        elif keyword == "RUN":
            for segment in re.split(r"&&|;|\|\|", args):
                words = segment.split()
                if "apt-get" in words and "install" in words:
                    after = words[words.index("install") + 1:]
                    current.packages += [w for w in after if not w.startswith("-") and "$" not in w]
        elif keyword == "ENTRYPOINT":
            if check(args.startswith("["), f"{where}: ENTRYPOINT in shell form (the tool would not get SIGTERM)"):
                current.entrypoint = json.loads(args)
        elif keyword == "EXPOSE":
            current.expose.update(int(p.split("/")[0]) for p in args.split())
    return stages, order


def help_text(tool, *sub):
    if not os.path.isfile(os.path.join(bin_dir, tool)):
        return None  # reported with the stage's tools
    r = run([os.path.join(bin_dir, tool), *sub, "--help"])
    check(r.returncode == 0, f"{tool} {' '.join(sub)} --help: exit {r.returncode}: {r.stderr.strip()}")
    return r.stdout


def help_flags(text):
    flags = set()
    for line in text.splitlines():
        m = re.match(r"^\s+((?:--?[A-Za-z][\w-]*,?)+)(\s|$)", line)
        if m:
            flags.update(f for f in m.group(1).split(",") if f)
    return flags


def help_subcommands(text):
    subs, inside = set(), False
    for line in text.splitlines():
        if line.startswith("Subcommands:"):
            inside = True
        elif inside and re.match(r"^  [\w-]+\s", line):
            subs.add(line.split()[0])
        elif inside and line and not line.startswith(" "):
            inside = False
    return subs


def package_of(path):
    """Debian package owning a library path (usrmerge: try both spellings)."""
    real = os.path.realpath(path)
    for p in (real, real[4:] if real.startswith("/usr/") else "/usr" + real, path):
        r = run(["dpkg-query", "-S", p])
        if r.returncode == 0:
            return r.stdout.split(":")[0]
    return None


def needed_packages(binary):
    needed = re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", run(["readelf", "-d", binary]).stdout)
    resolved = dict(re.findall(r"^\s*(\S+) => (/\S+)", run(["ldd", binary]).stdout, re.MULTILINE))
    out = {}
    for soname in needed:
        if SANITIZER_LIB.match(soname):
            continue
        if check(soname in resolved, f"{os.path.basename(binary)}: ldd does not resolve {soname}"):
            out[soname] = package_of(resolved[soname])
    return out


ignore_patterns = dockerignore_patterns()
for must in ("build", ".git"):  # a host CMake cache in the context would break the image's build
    check(ignored(must, ignore_patterns), f".dockerignore: '{must}' is not excluded")

stages, order = parse_dockerfile()
tools = cmake_tools()
runtime = [stages[n] for n in order if not stages[n].used_as_source]
check(runtime, "Dockerfile: no runtime stage (every stage is copied from)")
for st in runtime:
    check(st.tools, f"Dockerfile stage '{st.name}': copies no tool from the build stage")
    for t in st.tools:
        check(t in tools, f"Dockerfile stage '{st.name}': '{t}' is no tool target of the CMake files ({sorted(tools)})")
        check(os.path.isfile(os.path.join(bin_dir, t)), f"Dockerfile stage '{st.name}': '{t}' is not in {bin_dir}")
    if check(st.entrypoint, f"Dockerfile stage '{st.name}': no ENTRYPOINT"):
        check(st.entrypoint[0] in st.tools,
              f"Dockerfile stage '{st.name}': ENTRYPOINT {st.entrypoint[0]} is not a tool it copies")

# Runtime packages: they exist in the distribution, and cover what the tools link.
os_release = open("/etc/os-release").read() if os.path.exists("/etc/os-release") else ""
bases = {st.base for st in runtime}
same_distribution = bases == {"debian:12"} and "VERSION_CODENAME=bookworm" in os_release
if not same_distribution:
    skip(f"package checks: this machine is not the images' distribution ({sorted(bases)})")
elif not shutil.which("apt-cache") or run(["apt-cache", "show", "--no-all-versions", "libc6"]).returncode:
    skip("package names: apt-cache or its package lists are missing")
else:
    wanted = sorted({p for st in runtime for p in st.packages})
    # One call (each costs a read of the whole cache); it names the ones it has.
    known = set(re.findall(r"^Package: (\S+)", run(["apt-cache", "show", "--no-all-versions", *wanted]).stdout,
                           re.MULTILINE))
    for st in runtime:
        for p in st.packages:
            check(p in known, f"Dockerfile stage '{st.name}': apt-cache knows no package '{p}'")
if same_distribution and not all(shutil.which(t) for t in ("readelf", "ldd", "dpkg-query")):
    skip("linked libraries: readelf, ldd or dpkg-query missing")
elif same_distribution:
    for st in runtime:
        for t in st.tools:
            binary = os.path.join(bin_dir, t)
            if not os.path.isfile(binary):
                continue
            for soname, pkg in needed_packages(binary).items():
                if check(pkg, f"{t}: no Debian package owns {soname} (built against a library outside apt?)"):
                    check(pkg in BASE_IMAGE_PACKAGES or pkg in st.packages,
                          f"Dockerfile stage '{st.name}': {t} links {soname} from '{pkg}', which the stage does not install")

# ---- compose.yaml -------------------------------------------------------------------

INTERPOLATION = re.compile(r"\$\{(\w+)(?::?-([^}]*))?\}")


def interpolate(value, where):
    """Compose's ${VAR:-default} with the defaults: what `up` runs with nothing set."""
    def repl(m):
        check(m.group(2) is not None, f"{where}: ${{{m.group(1)}}} has no default")
        return m.group(2) or ""
    return INTERPOLATION.sub(repl, str(value)).replace("$$", "$")


def as_list(value, where):
    if value is None:
        return None
    words = shlex.split(value) if isinstance(value, str) else [str(v) for v in value]
    return [interpolate(w, where) for w in words]


def in_image(stage, path):
    """Whether a relative path, taken from the stage's WORKDIR, lands on a file COPY put there."""
    target = os.path.normpath(os.path.join(stage.workdir, path))
    for src, dest in stage.context_copies:
        if target == dest or target.startswith(dest + "/"):
            rel = os.path.relpath(target, dest)
            return os.path.exists(os.path.normpath(os.path.join(source, src, rel)))
    return False


compose = yaml.safe_load(open(compose_file))
services = compose.get("services") or {}
check(services, "compose.yaml: no services")
for key in compose:
    check(key in ("services", "volumes", "networks", "configs", "secrets") or key.startswith("x-"),
          f"compose.yaml: top-level key '{key}' (Compose v1 rejects 'name'; 'version' is obsolete)")
declared_volumes = set(compose.get("volumes") or {})
used_volumes = set()
image_target = {}
help_cache = {}

for name, svc in services.items():
    build = svc.get("build")
    if build is not None:
        if isinstance(build, str):
            build = {"context": build}
        context = os.path.normpath(os.path.join(os.path.dirname(compose_file), build.get("context", ".")))
        check(os.path.realpath(context) == os.path.realpath(source),
              f"service {name}: build context {context} is not the repository root")
        check(os.path.realpath(os.path.join(context, build.get("dockerfile", "Dockerfile"))) ==
              os.path.realpath(dockerfile), f"service {name}: build.dockerfile is not docker/Dockerfile")
        target = build.get("target")
        if check(target in stages and stages[target] in runtime,
                 f"service {name}: build target '{target}' is no runtime stage of the Dockerfile"):
            image = svc.get("image", name)
            check(image_target.setdefault(image, target) == target,
                  f"service {name}: image '{image}' is built from two stages")
for name, svc in services.items():
    image = svc.get("image")
    if not check(image in image_target, f"service {name}: image '{image}' is built by no service"):
        continue
    stage = stages[image_target[image]]
    where = f"service {name}"

    depends = svc.get("depends_on") or {}
    if isinstance(depends, list):  # short syntax: started is enough
        depends = {d: {} for d in depends}
    for dep, spec in depends.items():
        check(dep in services and dep != name, f"{where}: depends_on unknown service '{dep}'")
        check((spec or {}).get("condition", "service_started") in
              ("service_started", "service_healthy", "service_completed_successfully"),
              f"{where}: depends_on {dep}: unknown condition {spec}")

    for v in svc.get("volumes") or []:
        src = v.get("source") if isinstance(v, dict) else str(v).split(":")[0]
        if src and not src.startswith((".", "/", "~")):
            used_volumes.add(src)
            check(src in declared_volumes, f"{where}: volume '{src}' is not declared under volumes:")

    entrypoint = as_list(svc.get("entrypoint"), where) or stage.entrypoint
    command = as_list(svc.get("command"), where) or []
    for p in svc.get("ports") or []:
        if isinstance(p, dict):
            published, container = str(p.get("published", "")), str(p["target"])
        else:
            fields = str(p).split("/")[0].split(":")
            published, container = (fields[-2] if len(fields) > 1 else ""), fields[-1]
        check(int(container) in stage.expose, f"{where}: port {container} is not EXPOSEd by stage '{stage.name}'")
        # Clients take the frame port from the server's announcement, not from this mapping.
        check("--pub" not in command or published == container,
              f"{where}: port {p}: a server's host port must equal its container port")

    if not check(entrypoint, f"{where}: no entrypoint, neither its own nor stage '{stage.name}''s"):
        continue
    tool = os.path.basename(entrypoint[0])
    if not check(tool in stage.tools, f"{where}: runs '{tool}', which stage '{stage.name}' does not ship"):
        continue
    args = entrypoint[1:] + command
    if tool not in help_cache:
        help_cache[tool] = help_text(tool)
    text = help_cache[tool]
    if text is None:
        continue
    if args and args[0] in help_subcommands(text):
        text = help_text(tool, args[0])
        args = args[1:]
    known = help_flags(text)
    for i, a in enumerate(args):
        if a.startswith("-") and not re.match(r"^-\d", a):
            check(a.split("=")[0] in known, f"{where}: {tool} has no option '{a}' (its --help lists {sorted(known)})")
        elif re.match(r"^[\w.][\w./-]*\.(toml|lua|obj|h5)$", a) and not a.startswith("/"):
            check(in_image(stage, a), f"{where}: '{a}' is not in image stage '{stage.name}' (WORKDIR {stage.workdir})")
        m = re.match(r"^tcp://([^:/]+):(\d+)$", a)
        if m and i > 0 and args[i - 1] == "--connect":
            host, port = m.groups()
            if check(host in services, f"{where}: --connect {a}: no service '{host}'"):
                peer = as_list(services[host].get("command"), host) or []
                binds = {peer[k + 1] for k in range(len(peer) - 1) if peer[k] == "--cmd"}
                check(any(b.endswith(":" + port) for b in binds),
                      f"{where}: --connect {a}: service {host} binds --cmd {sorted(binds)}")

for v in declared_volumes - used_volumes:
    check(False, f"compose.yaml: volume '{v}' is declared but no service mounts it")

# ---- the tools' own verdicts --------------------------------------------------------

if shutil.which("yamllint"):
    r = run(["yamllint", "--strict", compose_file])
    check(r.returncode == 0, f"yamllint: {r.stdout.strip()} {r.stderr.strip()}")
else:
    skip("yamllint is not installed (scripts/install-deps installs it)")
if shutil.which("docker-compose"):
    # Validates without a daemon; PHASECAST_* from the caller's environment would change what it checks.
    env = {k: v for k, v in os.environ.items() if not k.startswith("PHASECAST_")}
    r = run(["docker-compose", "-f", compose_file, "config", "-q"], env=env)
    check(r.returncode == 0, f"docker-compose config: {r.stdout.strip()} {r.stderr.strip()}")
else:
    skip("docker-compose is not installed (scripts/install-deps installs it)")

if failures:
    sys.exit(f"{len(failures)} check(s) failed")
print(f"docker files: all checks passed ({len(stages)} stages, {len(services)} services)")
