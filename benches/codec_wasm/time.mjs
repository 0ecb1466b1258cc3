// Times decode_pages (src/lib.rs) over each file: median of REPEATS runs.
import { readFileSync } from "node:fs";

const [wasmPath, repeatsArg, ...files] = process.argv.slice(2);
const repeats = Number(repeatsArg);
const { instance } = await WebAssembly.instantiate(readFileSync(wasmPath));
const { alloc, decode_pages, memory } = instance.exports;
for (const file of files) {
  const bytes = readFileSync(file);
  const ptr = alloc(bytes.length);
  new Uint8Array(memory.buffer, ptr, bytes.length).set(bytes);
  const rates = [];
  let decoded = 0;
  for (let i = 0; i < repeats; i++) {
    const started = performance.now();
    decoded = decode_pages(ptr, bytes.length);
    const seconds = (performance.now() - started) / 1000;
    if (decoded < 0) throw new Error(`${file}: a page was refused`);
    rates.push(decoded / seconds);
  }
  rates.sort((a, b) => a - b);
  const median = rates[Math.floor(rates.length / 2)];
  console.log(
    `${file}: ${bytes.length} bytes stored, ${decoded} decoded; wasm decode median ` +
      `${(median / 1e6).toFixed(1)} MB/s (range ${(rates[0] / 1e6).toFixed(1)}..` +
      `${(rates[rates.length - 1] / 1e6).toFixed(1)}), ${repeats} runs`,
  );
}
