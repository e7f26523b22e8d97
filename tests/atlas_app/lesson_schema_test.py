#!/usr/bin/env python3
"""docs/lesson.schema.json against the lessons: every shipped lesson (data/lessons/*.yaml) must
validate and name the schema in its first line; every lesson in bad_lessons/schema/ must fail.

Uses the `jsonschema` package (Debian: python3-jsonschema) and PyYAML (python3-yaml), the same
draft-07 rules the YAML language server applies in editors.
usage: lesson_schema_test.py SCHEMA LESSONS_DIR BAD_DIR
"""
import glob
import json
import os
import sys

import jsonschema
import yaml


def main():
    schema_path, lessons_dir, bad_dir = sys.argv[1:4]
    with open(schema_path) as f:
        schema = json.load(f)
    jsonschema.Draft7Validator.check_schema(schema)
    validator = jsonschema.Draft7Validator(schema)
    failures = 0
    shipped = sorted(glob.glob(os.path.join(lessons_dir, "*.yaml")))
    bad = sorted(glob.glob(os.path.join(bad_dir, "*.yaml")))
    if len(shipped) < 3 or len(bad) < 3:
        print(f"FAIL: too few lessons found ({len(shipped)} shipped in {lessons_dir}, {len(bad)} bad in {bad_dir})")
        return 1
    for path in shipped:
        with open(path) as f:
            first = f.readline().strip()
            doc = yaml.safe_load(first + "\n" + f.read())
        want = "# yaml-language-server: $schema=../../docs/lesson.schema.json"
        if first != want:
            print(f"FAIL {path}: first line is '{first}', expected '{want}'")
            failures += 1
        errors = sorted(validator.iter_errors(doc), key=lambda e: list(e.path))
        for e in errors:
            print(f"FAIL {path}: {'/'.join(map(str, e.path))}: {e.message}")
        failures += len(errors)
        if not errors:
            print(f"ok   {path}: valid")
    for path in bad:
        with open(path) as f:
            doc = yaml.safe_load(f)
        errors = list(validator.iter_errors(doc))
        if not errors:
            print(f"FAIL {path}: a bad lesson passes the schema")
            failures += 1
        else:
            print(f"ok   {path}: rejected ({len(errors)} errors, first: {errors[0].message[:80]})")
    print(f"{len(shipped)} shipped lessons, {len(bad)} bad lessons, {failures} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
