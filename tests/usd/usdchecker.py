"""usdchecker for the usd-core wheel, which ships the validation framework but not the
command-line tool: opens a stage and runs every validator registered with
UsdValidation.ValidationRegistry (core, UsdGeom, UsdShade, UsdSkel, UsdUtils, ... rules), as
usdchecker does, over the stage's whole time range.

Usage: usdchecker.py STAGE

Prints one JSON object {"validators", "errors", "warnings", "messages"} and exits 1 when
any validator reports an error (2 when the stage does not open).
"""

import json
import sys

from pxr import Usd, UsdValidation


def main():
    stage = Usd.Stage.Open(sys.argv[1])
    if stage is None:
        print(json.dumps({"errors": 1, "messages": ["cannot open " + sys.argv[1]]}))
        return 2
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    context = UsdValidation.ValidationContext(validators)
    found = context.Validate(stage)
    kinds = UsdValidation.ValidationErrorType
    errors = [e for e in found if e.GetType() == kinds.Error]
    warnings = [e for e in found if e.GetType() == kinds.Warn]
    print(json.dumps({
        "validators": len(validators),
        "errors": len(errors),
        "warnings": len(warnings),
        "messages": [
            "%s %s: %s" % (e.GetType().displayName, e.GetName(), e.GetMessage())
            for e in found
        ],
    }))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
