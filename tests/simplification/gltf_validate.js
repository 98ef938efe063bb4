// Validate one glTF or GLB file with the Khronos glTF validator (npm package
// gltf-validator): node gltf_validate.js PACKAGE_DIR FILE prints its JSON report.
const fs = require("fs");
const path = require("path");
const validator = require(process.argv[2]);
const file = process.argv[3];
const data = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(data, {
    uri: path.basename(file),
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (err, d) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(d)));
      }),
  })
  .then((report) => console.log(JSON.stringify(report)))
  .catch((err) => { console.error(err); process.exit(2); });
