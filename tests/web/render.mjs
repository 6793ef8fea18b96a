// Renders a bake file with three.js in headless Chromium (SwiftShader WebGL, no GPU) and saves
// the canvas as PNG. usage: node render.mjs BAKE.glb OUT.png WIDTH HEIGHT EXPOSURE lambert|standard
import path from "node:path";
import { fileURLToPath } from "node:url";
import { renderPage } from "./chromium.mjs";

const here = path.dirname(fileURLToPath(import.meta.url));
const [glb, out, width, height, exposure, material] = process.argv.slice(2);
await renderPage({
  resolve: (url) => {
    if (url === "/bake.glb") return glb;
    const file = path.join(here, url);
    return file.startsWith(here) ? file : null;
  },
  query: `/page.html?file=/bake.glb&w=${width}&h=${height}&k=${exposure}&material=${material}`,
  width, height, out, loadingTitle: "voxgi bake in three.js",
});
