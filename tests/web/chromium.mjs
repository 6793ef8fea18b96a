// Shared by render.mjs and probes.mjs: serve a bake and static files on 127.0.0.1, open a page in
// headless Chromium (SwiftShader WebGL, no GPU), wait until it sets its title to "rendered", and save its
// canvas as PNG. resolve(url) maps a request path to a file (null: refused).
import fs from "node:fs";
import http from "node:http";
import path from "node:path";
import puppeteer from "puppeteer-core";

const types = { ".html": "text/html", ".js": "text/javascript", ".glb": "model/gltf-binary" };

export async function renderPage({ resolve, query, width, height, out, loadingTitle }) {
  const server = http.createServer((req, res) => {
    const file = resolve(decodeURIComponent(req.url.split("?")[0]));
    if (!file) { res.writeHead(403); res.end(); return; }
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
    await page.goto(`http://127.0.0.1:${port}${query}`);
    await page.waitForFunction((t) => document.title !== t, { timeout: 120000 }, loadingTitle);
    const title = await page.title();
    if (title !== "rendered") throw new Error(`${title}\n${logs.join("\n")}`);
    const dataUrl = await page.evaluate(() => document.querySelector("canvas").toDataURL("image/png"));
    fs.writeFileSync(out, Buffer.from(dataUrl.split(",")[1], "base64"));
    console.log(JSON.stringify({ out, logs }));
  } finally {
    await browser.close();
    server.close();
  }
}
