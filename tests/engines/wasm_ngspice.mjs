// Run one netlist in ngspice compiled to WebAssembly (the npm package eecircuit-engine) and
// print its vectors as JSON: node wasm_ngspice.mjs ENGINE_MODULE NETLIST
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const [engine, netlist] = process.argv.slice(2);
const { Simulation } = await import(pathToFileURL(engine).href);
const sim = new Simulation();
await sim.start();
sim.setNetList(readFileSync(netlist, "utf8"));
const result = await sim.runSim();
const data = {};
for (const vector of result.data) data[vector.name] = vector.values;
// exit once the pipe has taken all of it (the engine's worker would keep node alive)
process.stdout.write(JSON.stringify({ header: result.header, data }), () => process.exit(0));
