// Renders examples/three/index.html (a sphere lit by a bake's probes through THREE.LightProbe) in
// headless Chromium and saves the canvas as PNG. usage: node probes.mjs BAKE.glb OUT.png W H X,Y,Z R ALBEDO
import fs from "node:fs";
import http from "node:http";
import path from "node:path";
import { fileURLToPath } from "node:url";
import puppeteer from "puppeteer-core";

const here = path.dirname(fileURLToPath(import.meta.url));
const example = path.resolve(here, "..", "..", "examples", "three");
const [glb, out, width, height, at, radius, albedo] = process.argv.slice(2);
const types = { ".html": "text/html", ".js": "text/javascript", ".glb": "model/gltf-binary" };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split("?")[0]);
  let file;
  if (url === "/bake.glb") file = glb;
  else if (url.startsWith("/node_modules/")) file = path.join(here, url);
  else file = path.join(example, url === "/" ? "index.html" : url);
  if (file !== glb && !file.startsWith(here) && !file.startsWith(example)) { res.writeHead(403); res.end(); return; }
  fs.readFile(file, (err, data) => {
    if (err) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { "Content-Type": types[path.extname(file)] ?? "application/octet-stream" });
    res.end(data);
  });
});
await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
const port = server.address().port;
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
  args: ["--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
         "--disable-gpu-sandbox"],
});
try {
  const page = await browser.newPage();
  const logs = [];
  page.on("console", (m) => logs.push(m.text()));
  page.on("pageerror", (e) => logs.push(String(e)));
  await page.setViewport({ width: +width, height: +height });
  await page.goto(`http://127.0.0.1:${port}/index.html?file=/bake.glb&w=${width}&h=${height}&at=${at}` +
                  `&r=${radius}&albedo=${albedo}&still=1`);
  await page.waitForFunction(() => document.title !== "voxgi probes in three.js", { timeout: 120000 });
  const title = await page.title();
  if (title !== "rendered") throw new Error(`${title}\n${logs.join("\n")}`);
  const dataUrl = await page.evaluate(() => document.querySelector("canvas").toDataURL("image/png"));
  fs.writeFileSync(out, Buffer.from(dataUrl.split(",")[1], "base64"));
  console.log(JSON.stringify({ out, logs }));
} finally {
  await browser.close();
  server.close();
}
