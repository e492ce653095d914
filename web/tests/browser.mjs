// Browser test of the web page, run twice in headless Chromium (Debian's `chromium`, driven by playwright-core)
// on web/dist (built by web/build.sh) from a local server: once with the WebGPU flag set from
// ../shared/PLATFORM.md (the WebGPU build), once with WebGPU switched off (the WebGL2 build: CPU voxelization in
// wasm, WebGL2 drawing on SwiftShader). With WebGPU it
//  - waits for window.meshvoxStatus.ready and checks the default mesh's voxel count against the native CLI,
//  - changes the resolution through the page hook, then by typing into the panel's resolution field, and checks
//    the new counts against the CLI,
//  - opens a copy of Suzanne moved to UTM-like coordinates and expects the voxels of Suzanne at the origin;
//  - loads ../shared/meshes/suzanne.obj through the panel's Open… button and the file chooser it opens,
//    ../shared/meshes/gltf/Duck.gltf through the page's file input, and
//    drops gltf/box01.glb on the canvas, and checks their counts against the CLI,
//  - opens gltf/cube-external (a .gltf with its .bin and PNGs) picked as several files, and STL and PLY files,
//    and drops a coloured point cloud (a PLY without faces) on the canvas: its points in the status, the CLI's voxels,
//  - downloads the coloured Duck in each export format (.vox, .binvox, .npy with .colors.npy, .glb) and compares
//    each file byte for byte with the CLI's for the same input,
//  - loads a decimal OBJ box with tessellated faces on the grid's boundaries at 99 and checks page == CLI == shell,
//    then at 31 from the front hovers the middle of the viewport and reads the voxel from meshvoxStatus.hover,
//  - fails on any uncaught exception, panic or console error,
//  - compares a screenshot of the first view with tests/snapshots/web-default.<backend>.png (UPDATE_SNAPSHOTS=1
//    rewrites it; KEEP_SCREENSHOTS=1 also keeps each full-size screenshot as target/NAME.png, to look at).
// Without WebGPU it checks that the WebGL2 build is the one loaded, the default mesh, a resolution change and an
// opened coloured file against the CLI, the screenshot against its own golden, that a shared link (?mesh=…&r=…
// &axis=…&mode=…&cam=…) restores its view and that the address bar follows changes; and that a page with neither
// WebGPU nor WebGL2 says so. Both print their wasm's size and the time to the first voxels.
// The CLI reference is `meshvox voxelize --backend cpu` (the CPU reference voxelizer) from MESHVOX_BIN, by default
// target/debug/meshvox. Run: `node web/tests/browser.mjs` (tests/run.sh does, after `cargo test`).
import { chromium } from "playwright-core";
import { createServer } from "node:http";
import { readFile, readdir, writeFile, stat, mkdtemp, rm } from "node:fs/promises";
import { appendFileSync, existsSync, mkdirSync, mkdtempSync, rmSync } from "node:fs";
import { execFileSync } from "node:child_process";
import { tmpdir } from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const dist = path.join(root, "web/dist");
// CI set to a true value (true, 1, yes): then a missing tool or mesh fails the test instead of skipping.
const underCi = ["true", "1", "yes"].includes((process.env.CI ?? "").trim().toLowerCase());
/** `what` cannot run here: under CI an error; otherwise said loudly and recorded where tests/run.sh lists skips. */
function skipped(what, why) {
  if (underCi) throw new Error(`CI is set, but ${what} cannot run: ${why}`);
  console.log(`*** SKIPPED ${what}: ${why} ***`);
  mkdirSync(path.join(root, "target"), { recursive: true });
  appendFileSync(path.join(root, "target/test-skips.txt"), `browser test: ${what}: ${why}\n`);
}
const meshes = path.resolve(root, "../shared/meshes");
const bin = process.env.MESHVOX_BIN ?? path.join(root, "target/debug/meshvox");
const chromiumPath = process.env.CHROMIUM ?? "/usr/bin/chromium";
const snapshots = path.join(root, "tests/snapshots");
// Every file the test writes (CLI outputs, generated meshes) goes here, and goes away however the test ends.
const scratch = mkdtempSync(path.join(tmpdir(), "meshvox-web-test-"));
process.on("exit", () => rmSync(scratch, { recursive: true, force: true }));

let failures = 0;
function check(ok, what) {
  console.log(`${ok ? "ok  " : "FAIL"} ${what}`);
  if (!ok) failures++;
}

for (const [p, hint] of [[path.join(dist, "meshvox_bg.wasm"), "run `bash web/build.sh` first"],
  [path.join(dist, "meshvox_gl_bg.wasm"), "run `bash web/build.sh` first (it makes the WebGL2 build too)"],
  [bin, "build the CLI first (`cargo build`), or set MESHVOX_BIN"], [chromiumPath, "apt-get install chromium"]]) {
  if (!existsSync(p)) throw new Error(`${p} is missing: ${hint}`);
}
if (!existsSync(meshes)) skipped("the file-input part", `${meshes} is missing (this checkout has no ../shared)`);

/** Voxel count of the native CLI (CPU reference) for `spec` at `resolution`. */
function cliVoxels(spec, resolution, mode = "surface", axis = "longest") {
  const out = path.join(scratch, "cli.npy");
  const json = execFileSync(bin, ["voxelize", spec, "-r", String(resolution), "-o", out, "--stats-json",
    "--backend", "cpu", "--mode", mode, "--axis", axis], { encoding: "utf8", stdio: ["ignore", "pipe", "pipe"] });
  return JSON.parse(json.split("\n")[0]).voxels;
}

// A static server for web/dist, mounted in a subfolder as a deployment would be (the page must use relative URLs
// only); wasm needs its MIME type for streaming compilation.
const types = { ".html": "text/html", ".js": "text/javascript", ".wasm": "application/wasm" };
const mount = "/tools/meshvox/";
const server = createServer(async (req, res) => {
  const full = decodeURIComponent(new URL(req.url, "http://x").pathname);
  const name = full.startsWith(mount) ? full.slice(mount.length - 1) : "/outside-the-mount";
  const file = path.join(dist, name === "/" ? "index.html" : name);
  try {
    if (!file.startsWith(dist) || !(await stat(file)).isFile()) throw new Error("not found");
    res.writeHead(200, { "content-type": types[path.extname(file)] ?? "application/octet-stream" });
    res.end(await readFile(file));
  } catch {
    res.writeHead(404).end();
  }
});
await new Promise((r) => server.listen(0, "127.0.0.1", r));
const url = `http://127.0.0.1:${server.address().port}${mount}`;

const quiet = ["--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
  "--disable-quic"];
const flags = {
  webgpu: ["--no-sandbox", "--enable-unsafe-webgpu", "--enable-features=Vulkan", "--use-vulkan=swiftshader",
    "--use-angle=vulkan", "--use-webgpu-adapter=swiftshader", ...quiet],
  webgl2: ["--no-sandbox", "--disable-features=WebGPU", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    ...quiet],
};
const errors = [];

/** A page of a fresh browser (playwright-core gives each launch a fresh temporary profile, as PLATFORM.md asks),
 * its console errors collected into `errors`. */
async function openPage(browser, what) {
  const page = await browser.newPage({ viewport: { width: 960, height: 600 } });
  page.on("pageerror", (e) => errors.push(`uncaught (${what}): ${e.message}`));
  // Which of web/dist's files the page fetched, by name: the loader module must come only when a file needs it.
  page.fetched = [];
  page.on("request", (r) => page.fetched.push(path.basename(new URL(r.url()).pathname)));
  page.on("console", (m) => {
    if (m.type() === "error") errors.push(`console.error (${what}): ${m.text()}`);
    if (process.env.VERBOSE) console.log(`  [${m.type()}] ${m.text()}`);
  });
  return page;
}

/** The downloads the page's Export of `format` starts: `count` of them, or what came within a minute. */
async function exported(page, format, count) {
  const downloads = [];
  const onDownload = (d) => downloads.push(d);
  page.on("download", onDownload);
  await page.evaluate((f) => window.meshvoxExport(f), format);
  const deadline = Date.now() + 60_000;
  while (downloads.length < count && Date.now() < deadline) await page.waitForTimeout(100);
  page.off("download", onDownload);
  return downloads;
}

/** The sdf mode on the page: the slice moves without an error or a new voxelization, the exported .npy
 * holds the CLI's distances (the CPU reference) within 1e-5 of the band, with the same signs, and the exported
 * .nvdb is a level set NanoVDB's own tools pass (its values are the GPU's, so not the CLI's bytes). */
async function checkField(page, m, cliVoxelCount) {
  await page.evaluate(() => window.meshvoxSetSlice("x:0.3"));
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  const sliced = await page.evaluate(() => window.meshvoxStatus);
  check(!sliced.error && sliced.voxels === cliVoxelCount, `sdf: the slice at x:0.3 keeps the ${cliVoxelCount} voxels, no error`);
  const downloads = await exported(page, "npy", 1);
  if (downloads.length !== 1) return check(false, "sdf: export npy downloads one file");
  const saved = path.join(scratch, "page-sdf.npy");
  const reference = path.join(scratch, "cli-sdf.npy");
  await downloads[0].saveAs(saved);
  execFileSync(bin, ["voxelize", `builtin:${m.mesh}`, "-r", String(m.resolution), "--mode", "sdf", "-o", reference,
    "--backend", "cpu"], { stdio: "ignore" });
  const [a, b] = [await readFile(saved), await readFile(reference)];
  const header = 10 + a.readUInt16LE(8);
  const values = (buf) => new Float32Array(buf.buffer.slice(buf.byteOffset + header, buf.byteOffset + buf.length));
  const [pa, pb] = [values(a), values(b)];
  let worst = 0, signs = 0, background = 0;
  for (let i = 0; i < pb.length; i++) background = Math.max(background, Math.abs(pb[i]));
  for (let i = 0; i < Math.min(pa.length, pb.length); i++) {
    worst = Math.max(worst, Math.abs(pa[i] - pb[i]));
    if (Math.sign(pa[i]) !== Math.sign(pb[i])) signs++;
  }
  check(a.length === b.length && a.subarray(0, header).equals(b.subarray(0, header)) && worst <= 1e-5 * background &&
    signs === 0, `sdf: ${downloads[0].suggestedFilename()} from the page has the CLI's ${pb.length} distances ` +
    `(largest difference ${(worst / background).toExponential(2)} of the band, ${signs} signs differ)`);

  const nvdb = await exported(page, "nvdb", 1);
  if (nvdb.length !== 1) return check(false, "sdf: export nvdb downloads one file");
  const field = path.join(scratch, "page-sdf.nvdb");
  await nvdb[0].saveAs(field);
  const tool = (name, args) => {
    try {
      return execFileSync(name, args, { encoding: "utf8" });
    } catch (e) {
      // NanoVDB's tools come with libnanovdb-tools (tests/run.sh installs them); without them, say so loudly.
      if (e.code === "ENOENT") return skipped(`the ${name} check`, "not installed (apt-get install libnanovdb-tools)");
      throw e;
    }
  };
  const validated = tool("nanovdb_validate", ["-v", field]);
  const printed = tool("nanovdb_print", [field]);
  if (validated !== undefined) {
    check(validated.includes('Grid named "surface": passed') && !validated.includes("failed") &&
      /surface\s+float\s+SDF/.test(printed), `sdf: ${nvdb[0].suggestedFilename()} from the page is a level set ` +
      "nanovdb_validate passes and nanovdb_print lists (float, SDF)");
  }
}

/** A function that waits until meshvoxStatus on `page` satisfies `want` (a JSON-able partial status) and
 * returns the status. */
function statusOf(page) {
  return async (want, what) => {
    try {
      await page.waitForFunction((w) => {
        const s = window.meshvoxStatus;
        return s && (s.error || Object.entries(w).every(([k, v]) => s[k] === v));
      }, want, { timeout: 120_000 });
    } catch (e) {
      throw new Error(`${what}: meshvoxStatus never became ${JSON.stringify(want)} ` +
        `(last: ${JSON.stringify(await page.evaluate(() => window.meshvoxStatus))}; errors: ${errors.join(" | ")})`);
    }
    const s = await page.evaluate(() => window.meshvoxStatus);
    if (s.error) throw new Error(`${what}: the page reports an error: ${s.error}`);
    return s;
  };
}

/** The size of a file in web/dist and its gzip -9 size, as "N bytes (M gzipped)". */
async function sizeOf(name) {
  const bytes = await readFile(path.join(dist, name));
  const { gzipSync } = await import("node:zlib");
  return `${bytes.length} bytes (${gzipSync(bytes, { level: 9 }).length} gzipped)`;
}

async function withBrowser(kind, run) {
  const browser = await chromium.launch({ executablePath: chromiumPath, headless: true, args: flags[kind] });
  try {
    await run(browser);
  } finally {
    await browser.close();
  }
}

try {
  await withBrowser("webgpu", webgpuPath);
  await withBrowser("webgl2", webgl2Path);
} finally {
  server.close();
}
check(errors.length === 0, `no page errors or console errors${errors.length ? ": " + errors.join(" | ") : ""}`);
if (failures > 0) {
  console.log(`browser test: ${failures} check(s) failed`);
  process.exit(1);
}
console.log("browser test: all checks passed");

/** Opens the page and checks what both builds must show: the default mesh with the CLI's voxel count, the first
 * view against its golden (downscaled so goldens stay small), and a resolution change to 96 with the CLI's count.
 * Returns the page, its status waiter, the first and the changed status, and the time from navigation to the
 * first voxels. */
async function startAndCheckBasics(browser, label) {
  const page = await openPage(browser, label);
  const status = statusOf(page);
  const opened = performance.now();
  await page.goto(url);
  const first = await status({ ready: true }, `${label}: start`);
  const firstMs = performance.now() - opened;
  const defaultCli = cliVoxels(`builtin:${first.mesh}`, first.resolution);
  check(first.voxels === defaultCli,
    `${label}: default mesh builtin:${first.mesh} @${first.resolution}: page ${first.voxels} == CLI ${defaultCli}`);
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  await compareScreenshot(page, `web-default.${slug(first)}`);
  await page.evaluate(() => window.meshvoxSetResolution(96));
  const changed = await status({ ready: true, resolution: 96 }, `${label}: resolution change`);
  const changedCli = cliVoxels(`builtin:${changed.mesh}`, 96);
  check(changed.voxels === changedCli, `${label}: resolution 96: page ${changed.voxels} == CLI ${changedCli}`);
  return { page, status, first, firstMs, changed };
}

/** The page on the browser's WebGPU: everything the page does. */
async function webgpuPath(browser) {
  const { page, status, first, firstMs, changed } = await startAndCheckBasics(browser, "WebGPU");
  // The first voxels come from the CPU, before the page makes the compute pipelines; every later job runs on
  // the GPU.
  const where = first.voxelizer === "gpu" ? `compute passes ${first.gpu_ms.toFixed(1)} ms`
    : "on the CPU, before the GPU's pipelines are made";
  // The page's own wasm within the 1.5 MB gzipped issue 70 asks for; the loader module (glTF, JPEG and WebP) is
  // fetched apart, only when a file needs it.
  const gzipped = (await sizeOf("meshvox_bg.wasm")).match(/\((\d+) gzipped\)/)[1];
  check(Number(gzipped) <= 1_500_000, `the WebGPU build's wasm is ${gzipped} bytes gzipped, at most 1,500,000`);
  console.log(`loader module: meshvox_loader_bg.wasm ${await sizeOf("meshvox_loader_bg.wasm")}`);
  check(!page.fetched.includes("meshvox_loader_bg.wasm"), "the builtin meshes load without the loader module");
  console.log(`WebGPU build: meshvox_bg.wasm ${await sizeOf("meshvox_bg.wasm")}; ` +
    `first voxels ${firstMs.toFixed(0)} ms after navigation; adapter "${first.adapter}" ` +
    `(${first.backend}); ${first.mesh} @${first.resolution}: ${first.voxels} voxels in ${first.voxelize_ms.toFixed(1)} ms (${where})`);
  check(first.backend === "BrowserWebGpu", `the page draws with the browser's WebGPU (backend ${first.backend})`);
  const cliVersion = execFileSync(bin, ["--version"]).toString().trim();
  check(`meshvox ${first.version}` === cliVersion,
    `the page's version (meshvoxStatus.version ${first.version}) is the CLI's (${cliVersion})`);
  check(changed.voxelizer === "gpu" && changed.gpu_ms !== null,
    `after the first frame the page voxelizes on the GPU (resolution 96: voxelizer ${changed.voxelizer}, ` +
    `compute passes ${changed.gpu_ms?.toFixed(1)} ms)`);

  // And through the panel: click the slider's number field, type a value, press Enter.
  await clickLikeAUser(page, 136, 167);
  await page.keyboard.press("Control+A");
  await page.keyboard.type("128");
  await page.keyboard.press("Enter");
  const typed = await status({ ready: true, resolution: 128 }, "typing 128 into the resolution field");
  const typedCli = cliVoxels(`builtin:${typed.mesh}`, 128);
  check(typed.voxels === typedCli, `resolution 128 typed into the panel: page ${typed.voxels} == CLI ${typedCli}`);

  // The modes: solid (the surface plus the inside), the thin surface, the field and the shell (one voxel thick),
  // each the CLI's count; the cut-away only changes the view. Then back to the surface for the rest.
  check(typed.mode === "surface", `the page starts in surface mode (${typed.mode})`);
  for (const mode of ["solid", "surface6", "sdf", "shell", "surface"]) {
    await page.evaluate((m) => window.meshvoxSetMode(m), mode);
    const m = await status({ ready: true, mode }, `mode ${mode}`);
    const cli = cliVoxels(`builtin:${m.mesh}`, m.resolution, mode);
    check(m.voxels === cli, `mode ${mode} @${m.resolution}: page ${m.voxels} == CLI ${cli}`);
    if (mode === "sdf") await checkField(page, m, cli);
    if (mode === "solid") {
      await page.evaluate(() => window.meshvoxSetCut("x:0.5"));
      await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
      const cut = await page.evaluate(() => window.meshvoxStatus);
      check(!cut.error && cut.voxels === cli, `the cut-away keeps the solid's ${cli} voxels and shows no error`);
      await page.evaluate(() => window.meshvoxSetCut(""));
    }
  }

  if (existsSync(meshes)) {
    for (const rel of ["suzanne.obj", "gltf/Duck.gltf"]) {
      const file = path.join(meshes, rel);
      if (rel === "suzanne.obj") {
        // The user's way: click the panel's Open… button (drawn by egui at this spot of the 260-point panel),
        // which must open the browser's file chooser.
        const [chooser] = await Promise.all([page.waitForEvent("filechooser", { timeout: 15_000 }),
          clickLikeAUser(page, 37, 104)]);
        await chooser.setFiles(file);
      } else {
        await page.setInputFiles("#meshvox-file", file);
      }
      const s = await status({ ready: true, mesh: path.basename(file) }, `loading ${rel}`);
      const loaderFetches = page.fetched.filter((f) => f === "meshvox_loader_bg.wasm").length;
      check(loaderFetches === (rel.endsWith(".gltf") ? 1 : 0),
        `${rel}: the loader module fetched ${loaderFetches} time(s) (only for glTF, and once)`);
      const cli = cliVoxels(file, s.resolution);
      check(s.voxels === cli, `${rel} @${s.resolution} through ${rel === "suzanne.obj" ? "Open…" : "the file input"}: page ${s.voxels} == CLI ${cli} ` +
        `(${s.triangles} triangles, ${s.voxelize_ms.toFixed(1)} ms)`);
      if (rel === "suzanne.obj") {
        // How live the slider is: from a resolution change to its voxels in the status (printed, not asserted:
        // timings are benchmark results; bench/RESULTS.md records them).
        const target = s.resolution === 96 ? 97 : 96;
        const t0 = performance.now();
        await page.evaluate((r) => window.meshvoxSetResolution(r), target);
        const r = await status({ ready: true, resolution: target }, `Suzanne at ${target}`);
        console.log(`resolution change: Suzanne @${target} shows its ${r.voxels} voxels ${(performance.now() - t0).toFixed(0)} ms ` +
          `after the change (voxelize ${r.voxelize_ms.toFixed(1)} ms, compute passes ${r.gpu_ms.toFixed(1)} ms)`);
        check(r.voxels === cliVoxels(file, target), `Suzanne @${target} after a resolution change matches the CLI`);
      }
    }
    // Drag and drop: a real drop event on the canvas carrying the file, as a file manager would send it.
    const glb = path.join(meshes, "gltf/box01.glb");
    const dropped = await page.evaluateHandle(({ name, b64 }) => {
      const dt = new DataTransfer();
      dt.items.add(new File([Uint8Array.from(atob(b64), (c) => c.charCodeAt(0))], name));
      return dt;
    }, { name: path.basename(glb), b64: (await readFile(glb)).toString("base64") });
    await page.dispatchEvent("#meshvox_canvas", "drop", { dataTransfer: dropped });
    const s = await status({ ready: true, mesh: path.basename(glb) }, "dropping box01.glb");
    const cli = cliVoxels(glb, s.resolution);
    check(s.voxels === cli, `gltf/box01.glb @${s.resolution} dropped on the canvas: page ${s.voxels} == CLI ${cli}`);

    // Far from the origin: Suzanne moved to UTM-like coordinates (ten decimals) must give the voxels of Suzanne
    // where she was; f32 positions would have rounded her onto 0.5-unit steps.
    const suzanne = path.join(meshes, "suzanne.obj");
    const farObj = path.join(scratch, "suzanne-far.obj");
    const offset = [4500000.37, 5400000.81, 312.25];
    await writeFile(farObj, (await readFile(suzanne, "utf8")).split("\n").map((line) => {
      const w = line.trim().split(/\s+/);
      return w[0] === "v" ? "v " + [1, 2, 3].map((i) => (Number(w[i]) + offset[i - 1]).toFixed(10)).join(" ") : line;
    }).join("\n"));
    await page.setInputFiles("#meshvox-file", farObj);
    const far = await status({ ready: true, mesh: path.basename(farObj) }, "loading the far-away Suzanne");
    const nearCli = cliVoxels(suzanne, far.resolution);
    const farCli = cliVoxels(farObj, far.resolution);
    check(far.voxels === nearCli && farCli === nearCli,
      `Suzanne moved by ${offset} @${far.resolution}: page ${far.voxels} == CLI ${farCli} == CLI at the origin ${nearCli}`);

    // glTF as optimizers write it: the Duck through gltfpack (quantized and meshopt-compressed) and through
    // glTF-Transform's Draco compression opens in the page, coloured, with the CLI's voxels.
    for (const [tool, args, name] of [["gltfpack", ["-cc"], "duck-meshopt.glb"], ["gltf-transform", ["draco"], "duck-draco.glb"]]) {
      const out = path.join(scratch, name);
      const input = path.join(meshes, "gltf/Duck.glb");
      const toolArgs = tool === "gltfpack" ? ["-i", input, "-o", out, ...args] : [...args, input, out];
      execFileSync(path.join(root, "web/node_modules/.bin", tool), toolArgs, { stdio: "ignore" });
      await page.setInputFiles("#meshvox-file", out);
      const packed = await status({ ready: true, mesh: name }, `opening ${name} (${tool} ${args.join(" ")})`);
      const packedCli = cliVoxels(out, packed.resolution);
      check(packed.voxels === packedCli && packed.coloured && !packed.error,
        `${name} (${tool} ${args.join(" ")}) through the file input: page ${packed.voxels} == CLI ${packedCli}, coloured ${packed.coloured}`);
    }

    // A glTF with an external .bin and textures, picked together: it opens, coloured, with the CLI's voxels.
    const cube = path.join(meshes, "gltf/cube-external");
    const cubeFiles = (await readdir(cube)).filter((f) => !f.endsWith(".md")).map((f) => path.join(cube, f));
    await page.setInputFiles("#meshvox-file", cubeFiles);
    const ext = await status({ ready: true, mesh: "Cube.gltf" }, "opening Cube.gltf with its .bin and images");
    const extCli = cliVoxels(path.join(cube, "Cube.gltf"), ext.resolution);
    check(ext.voxels === extCli && ext.coloured,
      `gltf/cube-external picked as ${cubeFiles.length} files: page ${ext.voxels} == CLI ${extCli}, coloured ${ext.coloured}`);
    const fetches = page.fetched.filter((f) => f === "meshvox_loader_bg.wasm").length;
    check(fetches === 1, `the loader module was fetched once for every glTF since (${fetches})`);

    // Exports: the coloured Duck at 48 downloaded in each format, byte for byte the CLI's file for the same input.
    const duck = path.join(meshes, "gltf/Duck.glb");
    await page.setInputFiles("#meshvox-file", duck);
    await status({ ready: true, mesh: "Duck.glb" }, "loading Duck.glb");
    await page.evaluate(() => window.meshvoxSetResolution(48));
    await status({ ready: true, mesh: "Duck.glb", resolution: 48, coloured: true }, "Duck.glb at 48");
    const work = await mkdtemp(path.join(scratch, "export-"));
    for (const format of ["vox", "binvox", "npy", "vdb", "nvdb", "npz", "glb", "schem", "litematic", "nbt"]) {
      const expected = format === "npy" ? ["Duck-48.npy", "Duck-48.colors.npy"] : [`Duck-48.${format}`];
      const downloads = await exported(page, format, expected.length);
      const names = downloads.map((d) => d.suggestedFilename());
      check(JSON.stringify(names) === JSON.stringify(expected), `export ${format}: downloads ${names.join(", ")}`);
      const reference = path.join(work, `reference.${format}`);
      execFileSync(bin, ["voxelize", duck, "-r", "48", "-o", reference, "--backend", "cpu"], { stdio: "ignore" });
      for (const d of downloads) {
        const saved = path.join(work, d.suggestedFilename());
        await d.saveAs(saved);
        const ref = d.suggestedFilename().endsWith(".colors.npy") ? path.join(work, "reference.colors.npy") : reference;
        const [a, b] = [await readFile(saved), await readFile(ref)];
        check(a.equals(b), `${d.suggestedFilename()} from the page (${a.length} bytes) equals the CLI's (${b.length} bytes)`);
      }
    }
    await rm(work, { recursive: true, force: true });

    // A mesh picked while the loader module is still reading wins: the Duck handed over and the torus picked in
    // the same frame; the Duck's answer, when it comes, is dropped.
    const duckB64 = (await readFile(duck)).toString("base64");
    const callsBefore = await page.evaluate(() => window.meshvoxLoaderCalls);
    await page.evaluate((b64) => {
      window.meshvoxLoadFiles(["Duck.glb"], [Uint8Array.from(atob(b64), (c) => c.charCodeAt(0))]);
      window.meshvoxLoadBuiltin("torus");
    }, duckB64);
    await status({ ready: true, mesh: "torus" }, "the torus picked while the loader module reads the Duck");
    await page.waitForFunction((n) => window.meshvoxLoaderAnswers > n &&
      window.meshvoxLoaderAnswers === window.meshvoxLoaderCalls, callsBefore, { timeout: 60_000 });
    await page.waitForTimeout(1500);
    const kept = await page.evaluate(() => window.meshvoxStatus);
    check(kept.mesh === "torus" && !kept.error,
      `the torus picked while the loader module read the Duck stays after the Duck's answer (${kept.mesh})`);
  }

  // STL and PLY through the file input (files of the hostile corpus's valid half): the CLI's voxels, and the
  // PLY's vertex colours.
  for (const name of ["single-triangle.stl", "quad-with-colours.ply"]) {
    const file = path.join(root, "tests/corpus/odd", name);
    await page.setInputFiles("#meshvox-file", file);
    const s = await status({ ready: true, mesh: name }, `loading ${name}`);
    const cli = cliVoxels(file, s.resolution);
    check(s.voxels === cli && s.coloured === name.endsWith(".ply"),
      `${name} @${s.resolution}: page ${s.voxels} == CLI ${cli}, coloured ${s.coloured}`);
  }

  // OBJs textured with a PNG (read by the app itself, which decodes PNGs with the PNG decoder alone) and with a JPEG
  // (ImageMagick makes both; the app hands the JPEG's files to the loader module): each coloured grid's .vox
  // (voxels and palette) is the CLI's file.
  const texDir = await mkdtemp(path.join(scratch, "textured-obj-"));
  for (const [ext, want] of [["png", 0], ["jpg", 1]]) {
    const name = `${ext}-quad`;
    await writeFile(path.join(texDir, `${name}.obj`), `mtllib ${name}.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0.25\n` +
      "v 0 1 0.25\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl gradient\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n");
    await writeFile(path.join(texDir, `${name}.mtl`), `newmtl gradient\nmap_Kd gradient.${ext}\n`);
    execFileSync("convert", ["-size", "64x64", "gradient:orange-navy", path.join(texDir, `gradient.${ext}`)]);
    const calls = await page.evaluate(() => window.meshvoxLoaderCalls);
    await page.setInputFiles("#meshvox-file", [`${name}.obj`, `${name}.mtl`, `gradient.${ext}`].map((f) => path.join(texDir, f)));
    const q = await status({ ready: true, mesh: `${name}.obj` }, `an OBJ with a ${ext} texture`);
    const handed = (await page.evaluate(() => window.meshvoxLoaderCalls)) - calls;
    const [download] = await exported(page, "vox", 1);
    const saved = path.join(texDir, `${name}-page.vox`);
    await download.saveAs(saved);
    execFileSync(bin, ["voxelize", path.join(texDir, `${name}.obj`), "-r", String(q.resolution), "-o",
      path.join(texDir, `${name}-cli.vox`), "--backend", "cpu"], { stdio: "ignore" });
    const [fromPage, fromCli] = [await readFile(saved), await readFile(path.join(texDir, `${name}-cli.vox`))];
    check(q.coloured && fromPage.equals(fromCli) && handed === want, `an OBJ with a ${ext} texture @${q.resolution}: ` +
      `coloured ${q.coloured}, handed to the loader module ${handed} time(s), its .vox (${fromPage.length} bytes) ` +
      `equals the CLI's (${fromCli.length} bytes)`);
  }

  // A point cloud (a PLY without faces, as scanners write them): 5,000 points with decimals and colours on a
  // sphere far from the origin, dropped on the canvas. Each point sets its voxel; the status names the points.
  {
    const work = await mkdtemp(path.join(tmpdir(), "meshvox-cloud-"));
    const cloud = path.join(work, "scan.ply");
    const n = 5000;
    const lines = ["ply", "format ascii 1.0", `element vertex ${n}`, "property float x", "property float y",
      "property float z", "property uchar red", "property uchar green", "property uchar blue", "end_header"];
    for (let i = 0; i < n; i++) {
      // A Fibonacci sphere: deterministic, evenly spread.
      const z = 1 - (2 * i + 1) / n, r = Math.sqrt(1 - z * z), a = i * 2.399963229728653;
      const p = [1000.25 + r * Math.cos(a), -20.5 + r * Math.sin(a), 3.125 + z];
      lines.push(`${p.map((v) => v.toFixed(6)).join(" ")} ${i % 256} ${(7 * i) % 256} 128`);
    }
    await writeFile(cloud, lines.join("\n") + "\n");
    const dropped = await page.evaluateHandle(({ name, text }) => {
      const dt = new DataTransfer();
      dt.items.add(new File([text], name));
      return dt;
    }, { name: "scan.ply", text: await readFile(cloud, "utf8") });
    await page.dispatchEvent("#meshvox_canvas", "drop", { dataTransfer: dropped });
    const s = await status({ ready: true, mesh: "scan.ply" }, "dropping a point cloud");
    const cli = cliVoxels(cloud, s.resolution);
    check(s.points === n && s.triangles === 0 && s.voxels === cli && s.coloured,
      `a ${n}-point cloud dropped on the canvas @${s.resolution}: ${s.points} points, page ${s.voxels} == CLI ${cli} voxels, coloured ${s.coloured}`);
    await rm(work, { recursive: true, force: true });
  }

  // A user's file: a unit box centred on the origin whose faces are jittered 7x7 grids of decimal points,
  // triangulated (as remeshers and CAD exporters write them), at 99 voxels: every face lies on a grid boundary,
  // the first or the last, so every voxel of the grid's shell and no other must be set (the case that once lost
  // the last layer of each axis). Made here, so it runs without ../shared too.
  const boxObj = path.join(scratch, "tessellated-box.obj");
  await writeFile(boxObj, tessellatedBox(7, 0x5eed));
  await page.setInputFiles("#meshvox-file", boxObj);
  await status({ ready: true, mesh: path.basename(boxObj) }, "loading the tessellated box");
  await page.evaluate(() => window.meshvoxSetResolution(99));
  const box = await status({ ready: true, mesh: path.basename(boxObj), resolution: 99 }, "the box at 99");
  const boxCli = cliVoxels(boxObj, 99);
  const shell = 99 ** 3 - 97 ** 3;
  check(box.voxels === boxCli && boxCli === shell,
    `decimal tessellated box @99: page ${box.voxels} == CLI ${boxCli} == the grid's shell ${shell}`);

  // Hovering: at 31 voxels, from the front, the pointer in the middle of the viewport (right of the 260-point
  // panel) is over the middle voxel of the box's front face, (15, 15, 30).
  await page.evaluate(() => window.meshvoxSetResolution(31));
  await status({ ready: true, resolution: 31 }, "the box at 31");
  await page.evaluate(() => window.meshvoxSetView("front"));
  await page.mouse.move((260 + 960) / 2, 300);
  const hovered = await page.waitForFunction(() => JSON.stringify(window.meshvoxStatus?.hover) === "[15,15,30]", null,
    { timeout: 20_000 }).then(() => true, () => false);
  const hover = await page.evaluate(() => window.meshvoxStatus.hover);
  check(hovered, `hovering the middle of the box's front face names voxel [15,15,30] (meshvoxStatus.hover ${JSON.stringify(hover)})`);
  await page.mouse.move(5, 590);

  // The Screenshot button's download: a PNG of exactly the viewport (the canvas right of the panel).
  const shots = [];
  const onShot = (d) => shots.push(d);
  page.on("download", onShot);
  await page.evaluate(() => window.meshvoxScreenshot());
  for (const deadline = Date.now() + 30_000; shots.length === 0 && Date.now() < deadline;) await page.waitForTimeout(100);
  page.off("download", onShot);
  if (shots.length === 1) {
    const png = await readFile(await shots[0].path());
    const [w, h] = [png.readUInt32BE(16), png.readUInt32BE(20)];
    const viewport = await page.evaluate(() => {
      const c = document.getElementById("meshvox_canvas");
      return [c.width, c.height];
    });
    check(png.subarray(1, 4).toString() === "PNG" && Math.abs(w - (viewport[0] - 260)) <= 2 && h === viewport[1],
      `Screenshot downloads ${shots[0].suggestedFilename()}, ${w}x${h}: the viewport of the ${viewport.join("x")} canvas`);
  } else {
    check(false, `Screenshot downloads one PNG (got ${shots.length})`);
  }

  // Broken files from tests/corpus/bad through the file input: the panel shows one line naming the file, and the
  // page keeps working. Then a resolution the wasm heap cannot hold: refused with what fits, nothing allocated.
  const afterError = async (want, what) => {
    await page.waitForFunction((w) => {
      const s = window.meshvoxStatus;
      return s && !s.error && Object.entries(w).every(([k, v]) => s[k] === v);
    }, want, { timeout: 60_000 }).catch(async () => {
      throw new Error(`${what}: never recovered (last: ${JSON.stringify(await page.evaluate(() => window.meshvoxStatus))})`);
    });
    return page.evaluate(() => window.meshvoxStatus);
  };
  for (const name of ["index-count-past-view.gltf", "two-vertex-face.obj", "wrong-magic.glb", "random-bytes.glb"]) {
    await page.setInputFiles("#meshvox-file", path.join(root, "tests/corpus/bad", name));
    await page.waitForFunction((n) => window.meshvoxStatus?.error?.includes(n), name, { timeout: 30_000 });
    const s = await page.evaluate(() => window.meshvoxStatus);
    check(!s.error.includes("\n"), `bad file ${name}: the page shows "${s.error}"`);
  }
  await page.evaluate(() => window.meshvoxSetResolution(20000));
  await page.waitForFunction(() => window.meshvoxStatus?.error?.includes("largest resolution that fits"), null,
    { timeout: 30_000 });
  const tooBig = await page.evaluate(() => window.meshvoxStatus.error);
  check(/“Resolution: \d+”/.test(tooBig), `resolution 20000 refused, naming what fits in the panel's words: "${tooBig}"`);
  await page.evaluate(() => window.meshvoxSetResolution(72));
  const recovered = await afterError({ ready: true, resolution: 72 }, "after the bad files");
  const recoveredCli = cliVoxels(boxObj, 72);
  check(recovered.mesh === path.basename(boxObj) && recovered.voxels === recoveredCli,
    `after the bad files the page still voxelizes: the box @72 ${recovered.voxels} == CLI ${recoveredCli}`);
  await rm(boxObj, { force: true });

}

/** The page without WebGPU: the WebGL2 build, CPU voxelization in wasm; shared links; no WebGL2 either. */
async function webgl2Path(browser) {
  const { page, status, first, firstMs, changed } = await startAndCheckBasics(browser, "WebGL2");
  const build = await page.evaluate(() => window.meshvoxStarted?.build);
  console.log(`WebGL2 build: meshvox_gl_bg.wasm ${await sizeOf("meshvox_gl_bg.wasm")}; ` +
    `first voxels ${firstMs.toFixed(0)} ms after navigation; adapter "${first.adapter}" (${first.backend}); ` +
    `${first.mesh} @${first.resolution}: ${first.voxels} voxels in ${first.voxelize_ms.toFixed(1)} ms on the CPU`);
  check(build === "webgl2" && first.backend === "Gl" && first.voxelizer === "cpu",
    `without WebGPU the page runs the WebGL2 build (build ${build}, backend ${first.backend}, voxelizer ${first.voxelizer})`);
  const search = () => page.evaluate(() => decodeURIComponent(location.search));
  await page.waitForFunction(() => location.search.includes("r=96"), null, { timeout: 10_000 }).catch(() => {});
  const afterChange = await search();
  check(afterChange.includes(`mesh=${changed.mesh}`) && afterChange.includes("r=96") && afterChange.includes("cam="),
    `the address bar follows the view: ${afterChange}`);

  // An opened file: the coloured Duck (or, without ../shared, the tessellated box made here).
  const file = existsSync(meshes) ? path.join(meshes, "gltf/Duck.glb") : path.join(scratch, "tessellated-box-gl.obj");
  if (!existsSync(meshes)) await writeFile(file, tessellatedBox(5, 0xb0c5));
  await page.setInputFiles("#meshvox-file", file);
  const opened2 = await status({ ready: true, mesh: path.basename(file) }, `WebGL2: opening ${path.basename(file)}`);
  const fileCli = cliVoxels(file, opened2.resolution);
  check(opened2.voxels === fileCli && opened2.coloured === file.endsWith(".glb"),
    `WebGL2: ${path.basename(file)} @${opened2.resolution} through the file input: page ${opened2.voxels} == CLI ` +
    `${fileCli}, coloured ${opened2.coloured} (${opened2.voxelize_ms.toFixed(0)} ms)`);
  const withFile = await search();
  check(withFile.includes(`file=${path.basename(file)}`), `a file's name (not its content) goes into the link: ${withFile}`);

  // A shared link restores its view: mesh, resolution, axis, mode and camera; the camera is written back as given.
  const shared = await openPage(browser, "WebGL2 link");
  const cam = "30,20,3.5,0.5,0.25,0.5";
  await shared.goto(`${url}?mesh=torus&r=40&axis=y&mode=solid&cam=${cam}`);
  const linked = await statusOf(shared)({ ready: true }, "opening a shared link");
  const linkedCli = cliVoxels("builtin:torus", 40, "solid", "y");
  await shared.waitForFunction(() => location.search.includes("cam="), null, { timeout: 10_000 }).catch(() => {});
  const linkedSearch = await shared.evaluate(() => decodeURIComponent(location.search));
  check(linked.mesh === "torus" && linked.resolution === 40 && linked.mode === "solid" && linked.voxels === linkedCli &&
    linkedSearch.includes(`cam=${cam}`) && linkedSearch.includes("axis=y"),
    `a shared link restores torus @40 along y, solid (${linked.voxels} == CLI ${linkedCli}) and its camera: ${linkedSearch}`);

  // Neither WebGPU nor WebGL2: the page says so instead of showing a blank canvas.
  const plain = await openPage(browser, "no WebGL2");
  await plain.addInitScript(() => {
    delete Navigator.prototype.gpu;
    const getContext = HTMLCanvasElement.prototype.getContext;
    HTMLCanvasElement.prototype.getContext = function (kind, ...rest) {
      return kind === "webgl2" ? null : getContext.call(this, kind, ...rest);
    };
  });
  await plain.goto(url);
  await plain.waitForFunction(() => window.meshvoxStatus?.error, null, { timeout: 30_000 });
  const none = await plain.evaluate(() => ({ status: window.meshvoxStatus,
    text: document.getElementById("meshvox-message").innerText,
    visible: !document.getElementById("meshvox-message").hidden }));
  check(none.status.error === "no-webgpu-or-webgl2" && none.visible && none.text.includes("neither WebGPU nor WebGL2"),
    `without WebGPU and WebGL2 the page says so ("${none.text.split("\n")[0]}")`);
}

/** OBJ text of the box [-0.5, 0.5]^3, each face an m x m grid of cells with jittered inner points, written with
 * ten decimals (so almost no coordinate is exact in binary), two triangles per cell. */
function tessellatedBox(m, seed) {
  let state = seed;
  const random = () => ((state = (state * 1103515245 + 12345) % 2147483648) / 2147483648);
  const lines = [];
  let count = 0;
  for (let axis = 0; axis < 3; axis++) {
    for (const side of [-0.5, 0.5]) {
      const id = [];
      for (let i = 0; i <= m; i++) {
        for (let j = 0; j <= m; j++) {
          const inner = (k) => k > 0 && k < m;
          const u = i / m - 0.5 + (inner(i) ? (random() - 0.5) * 0.6 / m : 0);
          const v = j / m - 0.5 + (inner(j) ? (random() - 0.5) * 0.6 / m : 0);
          const p = [0, 0, 0];
          p[axis] = side;
          p[(axis + 1) % 3] = u;
          p[(axis + 2) % 3] = v;
          lines.push(`v ${p.map((c) => c.toFixed(10)).join(" ")}`);
          id.push(++count);
        }
      }
      const at = (i, j) => id[i * (m + 1) + j];
      for (let i = 0; i < m; i++) {
        for (let j = 0; j < m; j++) {
          lines.push(`f ${at(i, j)} ${at(i + 1, j)} ${at(i + 1, j + 1)}`, `f ${at(i, j)} ${at(i + 1, j + 1)} ${at(i, j + 1)}`);
        }
      }
    }
  }
  return lines.join("\n") + "\n";
}

/** Hovers, then presses and releases a few frames apart: egui decides what is under the pointer from the
 * previous frame, so an instant move-press-release can miss a widget on a busy machine. */
async function clickLikeAUser(page, x, y) {
  await page.mouse.move(x, y);
  await page.waitForTimeout(250);
  await page.mouse.down();
  await page.waitForTimeout(80);
  await page.mouse.up();
}

function slug(s) {
  const name = (s.adapter.split(/\s+/)[0] || "unknown").toLowerCase();
  return `${s.backend === "Gl" ? "webgl2" : "webgpu"}-${name}`.replace(/[^a-z0-9-]/g, "");
}

/** Compares a 256-pixel-wide screenshot with tests/snapshots/NAME.png using ImageMagick, with a tolerance for
 * anti-aliasing and text rasterisation differences. */
async function compareScreenshot(page, name) {
  const work = await mkdtemp(path.join(scratch, "shot-"));
  const full = path.join(work, "full.png");
  const small = path.join(snapshots, `${name}.new.png`);
  const golden = path.join(snapshots, `${name}.png`);
  await page.screenshot({ path: full });
  if (process.env.KEEP_SCREENSHOTS) execFileSync("cp", [full, path.join(root, "target", `${name}.png`)]);
  execFileSync("convert", [full, "-resize", "256x256", "-strip", "-define", "png:compression-level=9", small]);
  await rm(work, { recursive: true, force: true });
  if (process.env.UPDATE_SNAPSHOTS) {
    execFileSync("mv", [small, golden]);
    console.log(`wrote ${path.relative(root, golden)}`);
    return;
  }
  if (!existsSync(golden)) {
    check(false, `screenshot golden ${path.relative(root, golden)} exists (UPDATE_SNAPSHOTS=1 writes it; ` +
      `the new image is ${path.relative(root, small)})`);
    return;
  }
  // Pixels differing by more than 10% of the range in any channel, out of 256x160.
  let differing;
  try {
    differing = Number(execFileSync("compare", ["-metric", "AE", "-fuzz", "10%", golden, small,
      path.join(snapshots, `${name}.diff.png`)], { encoding: "utf8", stdio: ["ignore", "pipe", "pipe"] }));
  } catch (e) {
    // `compare` exits 1 when the images differ and prints the metric on stderr.
    differing = Number(String(e.stderr).trim().split(/\s+/)[0]);
  }
  const ok = Number.isFinite(differing) && differing <= 0.01 * 256 * 160;
  check(ok, `screenshot matches ${path.relative(root, golden)} (${differing} pixels differ by >10%, limit 1%)`);
  if (ok) {
    await rm(small, { force: true });
    await rm(path.join(snapshots, `${name}.diff.png`), { force: true });
  }
}
