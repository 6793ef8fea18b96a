// The irradiance probes of a voxgi bake in three.js: a GLTFLoader plugin that reads the probe grid from
// the bake's root VOXGI_lightmap extension (block "probes", version 2: see the README's "Output: the bake
// file"), and a grid whose shAt(position) gives the order-2 spherical harmonics of the light at any
// point, trilinear between the valid probes around it, ready for THREE.LightProbe. Usage:
//
//   const loader = new GLTFLoader();
//   loader.register((parser) => new VoxgiProbesPlugin(parser));
//   const gltf = await loader.loadAsync("bake.glb");
//   const grid = gltf.userData.voxgiProbes;            // null when the bake has none
//   const probe = new THREE.LightProbe();  scene.add(probe);
//   probe.sh.copy(grid.shAt(movingObject.position));   // each frame, as the object moves
//
// The SH are three.js's own basis and order (Y00, Y1-1, Y10, Y11, Y2-2, Y2-1, Y20, Y21, Y22) of the
// incident radiance, so LightProbe's irradiance is the probes' irradiance. Order 2 cannot hold a small
// lamp's light (it overshoots facing it and glows facing away); voxview reads the probes' irradiance
// maps instead, with visibility (the file has them too).
import * as THREE from "three";

export class VoxgiProbesPlugin {
  constructor(parser) { this.parser = parser; this.name = "VOXGI_lightmap"; }

  async afterRoot(gltf) {
    const ext = (this.parser.json.extensions || {}).VOXGI_lightmap;
    const block = ext && ext.probes;
    gltf.userData.voxgiProbes = null;
    if (!block) return;
    if (block.version !== 2) throw new Error(`voxgi probe block version ${block.version}: this reader reads 2`);
    const view = async (index) => new Uint8Array(await this.parser.getDependency("bufferView", index));
    const sh = await view(block.sh.bufferView);
    const valid = await view(block.valid.bufferView);
    gltf.userData.voxgiProbes = new VoxgiProbeGrid(block, sh, valid);
  }
}

export class VoxgiProbeGrid {
  constructor(block, shBytes, validBytes) {
    this.origin = new THREE.Vector3(...block.origin);
    this.spacing = block.spacing;
    this.dims = block.dims;
    const n = this.dims[0] * this.dims[1] * this.dims[2];
    // copied so that the floats are aligned whatever the bufferView's offset
    this.sh = new Float32Array(shBytes.slice().buffer, 0, n * 27);
    this.valid = validBytes.slice(0, n);
  }

  // THREE.SphericalHarmonics3 of the light at `position`: the valid probes of its grid cell, trilinear
  // weights renormalised over them (none valid: zero light).
  shAt(position, out = new THREE.SphericalHarmonics3()) {
    const [nx, ny, nz] = this.dims;
    const g = position.clone().sub(this.origin).divideScalar(this.spacing);
    const base = [g.x, g.y, g.z].map((v, a) => Math.min(Math.max(Math.floor(v), 0), Math.max(this.dims[a] - 2, 0)));
    const frac = [g.x, g.y, g.z].map((v, a) => (this.dims[a] > 1 ? Math.min(Math.max(v - base[a], 0), 1) : 0));
    out.zero();
    let total = 0;
    for (let corner = 0; corner < 8; corner++) {
      const off = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
      const idx = off.map((o, a) => Math.min(base[a] + o, this.dims[a] - 1));
      const probe = idx[0] + nx * (idx[1] + ny * idx[2]);
      if (!this.valid[probe]) continue;
      const w = off.reduce((p, o, a) => p * (o ? frac[a] : 1 - frac[a]), 1);
      if (w <= 0) continue;
      for (let c = 0; c < 9; c++) {
        const k = (probe * 9 + c) * 3;
        out.coefficients[c].x += w * this.sh[k];
        out.coefficients[c].y += w * this.sh[k + 1];
        out.coefficients[c].z += w * this.sh[k + 2];
      }
      total += w;
    }
    if (total > 0) out.scale(1 / total);
    return out;
  }
}
