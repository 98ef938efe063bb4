// Bundles viewers.js and three.js into ../static/viewers.min.js, its first line naming the
// SHA-256 of the sources it was built from (tests/test_viewer_bundle.py checks them).
import { createHash } from "node:crypto";
import { readFileSync } from "node:fs";
import { build } from "esbuild";

const SOURCES = ["viewers.js", "package-lock.json"];
const sha256 = (file) => createHash("sha256").update(readFileSync(file)).digest("hex");
const built = SOURCES.map((file) => `${file} sha256:${sha256(file)}`).join(", ");

await build({
  entryPoints: ["viewers.js"],
  bundle: true,
  minify: true,
  format: "iife",
  globalName: "NeurenderViewers",
  legalComments: "eof",
  outfile: "../static/viewers.min.js",
  banner: { js: `/* built from ${built} */` },
});
