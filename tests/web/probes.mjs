// Renders examples/three/index.html (a sphere lit by a bake's probes through THREE.LightProbe) in
// headless Chromium and saves the canvas as PNG. usage: node probes.mjs BAKE.glb OUT.png W H X,Y,Z R ALBEDO
import path from "node:path";
import { fileURLToPath } from "node:url";
import { renderPage } from "./chromium.mjs";

const here = path.dirname(fileURLToPath(import.meta.url));
const example = path.resolve(here, "..", "..", "examples", "three");
const [glb, out, width, height, at, radius, albedo] = process.argv.slice(2);
await renderPage({
  resolve: (url) => {
    if (url === "/bake.glb") return glb;
    const file = url.startsWith("/node_modules/") ? path.join(here, url) : path.join(example, url);
    return file.startsWith(here) || file.startsWith(example) ? file : null;
  },
  query: `/index.html?file=/bake.glb&w=${width}&h=${height}&at=${at}&r=${radius}&albedo=${albedo}&still=1`,
  width, height, out, loadingTitle: "voxgi probes in three.js",
});
