// Print Foxglove's official JSON schemas (npm @foxglove/schemas) as one JSON object
// keyed by schema name ("foxglove.LocationFix", ...), for scripts/validate_export.py.
const schemas = require("@foxglove/schemas/jsonschema");
const out = {};
for (const [key, schema] of Object.entries(schemas)) {
  out[schema.title || `foxglove.${key}`] = schema;
}
process.stdout.write(JSON.stringify(out));
