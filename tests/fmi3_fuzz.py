"""Fuzz harness of the FMI 3.0 FMUs (tests/test_fmu_fuzz.py runs it as a script).

    python tests/fmi3_fuzz.py SEED SEQUENCES CALLS DIR TOKEN [DIR TOKEN ...]

Each sequence runs in a forked child process (the parent never loads an FMU), which dlopens one of
the unzipped FMI 3.0 FMUs and makes CALLS random fmi3 calls through ctypes, with an oracle of the
FMI 3.0 co-simulation state machine: calls in the wrong state, invalid value references (time,
der(u) in the wrong role, outputs set, unknown references), NaN/Inf, out-of-range values, zero,
negative, huge and off-time steps, nValues != nValueReferences, types the FMU does not have,
event-mode / model-exchange / clock / configuration functions, FMU states across instances,
corrupt serialized bytes. The parent counts crashes (a signal), hangs (timeout), and what the child
reports; printed as "key value" lines like tests/c_host/fmu_fuzz.c:

    invalid       calls the oracle says must be refused
    invalid_ok    ... that were answered fmi3OK or fmi3Warning (must be 0)
    unlogged      ... refused without a message to the logger (must be 0)
    nonfinite_ok  GetFloat64 answered OK with a non-finite value (must be 0)
    roundtrips / roundtrip_bad, serial_roundtrips / serial_bad: FMU state restored then re-stepped
                  gives the same outputs to the last bit
"""

from __future__ import annotations

import ctypes as C
import json
import math
import os
import random
import select
import signal
import sys
import time

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
U32P, DBLP = C.POINTER(C.c_uint32), C.POINTER(C.c_double)
LOG = C.CFUNCTYPE(None, C.c_void_p, C.c_int, C.c_char_p, C.c_char_p)


def _variables(d: str) -> dict:
    import xml.etree.ElementTree as ET

    root = ET.parse(os.path.join(d, "modelDescription.xml")).getroot()
    out = {}
    for v in root.find("ModelVariables"):
        out[v.get("name")] = dict(
            type=v.tag,
            vr=int(v.get("valueReference")),
            causality=v.get("causality"),
            variability=v.get("variability"),
            min=v.get("min"),
            max=v.get("max"),
        )
    return out


class Fmu:
    def __init__(self, d: str, token: str):
        ident = os.path.basename(d.rstrip("/"))
        self.lib = C.CDLL(os.path.join(d, "binaries", "x86_64-linux", ident + ".so"), mode=os.RTLD_LOCAL)
        self.d, self.token = d, token
        self.vars = _variables(d)
        self.logged = 0
        self._log = LOG(self._on_log)
        L = self.lib
        L.fmi3InstantiateCoSimulation.restype = C.c_void_p
        L.fmi3InstantiateCoSimulation.argtypes = [
            C.c_char_p,
            C.c_char_p,
            C.c_char_p,
            C.c_bool,
            C.c_bool,
            C.c_bool,
            C.c_bool,
            U32P,
            C.c_size_t,
            C.c_void_p,
            LOG,
            C.c_void_p,
        ]

    def _on_log(self, env, status, cat, msg):
        self.logged += 1

    def f(self, name, *argtypes):
        fn = getattr(self.lib, name)
        fn.restype = C.c_int
        fn.argtypes = [C.c_void_p, *argtypes]
        return fn

    def instantiate(self, name=b"fuzz"):
        res = (os.path.join(self.d, "resources") + "/").encode()
        return self.lib.fmi3InstantiateCoSimulation(
            name, self.token.encode(), res, False, False, False, False, None, 0, None, self._log, None
        )


def arr(kind, vals):
    return (kind * max(1, len(vals)))(*vals)


def run_sequence(fmus: list[Fmu], rng: random.Random, calls: int) -> dict:
    cnt = dict(
        calls=0,
        invalid=0,
        invalid_ok=0,
        unlogged=0,
        nonfinite_ok=0,
        roundtrips=0,
        roundtrip_bad=0,
        serial_roundtrips=0,
        serial_bad=0,
    )
    fmu = rng.choice(fmus)
    inst = fmu.instantiate()
    if not inst:
        raise RuntimeError("instantiate failed")
    st = "inst"
    t = 0.0
    V = fmu.vars
    reals = [v for v in V.values() if v["type"] == "Float64"]
    outputs = [v["vr"] for v in reals if v["causality"] == "output"]
    inputs = [v for v in reals if v["causality"] == "input"]
    tvr = V["time"]["vr"]
    all_vr = [v["vr"] for v in V.values()] + [9999, 2**31]
    set64 = fmu.f("fmi3SetFloat64", U32P, C.c_size_t, DBLP, C.c_size_t)
    get64 = fmu.f("fmi3GetFloat64", U32P, C.c_size_t, DBLP, C.c_size_t)
    step = fmu.f("fmi3DoStep", C.c_double, C.c_double, C.c_bool, *[C.POINTER(C.c_bool)] * 3, DBLP)
    flags = [C.c_bool() for _ in range(3)]
    last = C.c_double()
    states: list = []

    def do_step(tt, h):
        return step(inst, tt, h, False, *[C.byref(x) for x in flags], C.byref(last))

    def outputs_now():
        vals = (C.c_double * len(outputs))()
        s = get64(inst, arr(C.c_uint32, outputs), len(outputs), vals, len(outputs))
        return s, list(vals)

    def expect_refused(status, before):
        cnt["invalid"] += 1
        if status in (OK, WARNING):
            cnt["invalid_ok"] += 1
        elif fmu.logged == before:
            cnt["unlogged"] += 1

    for _ in range(calls):
        cnt["calls"] += 1
        op = rng.randrange(16)
        if st in ("inst", "init") and rng.random() < 0.5:  # spend most calls past initialisation
            op = 0 if st == "inst" else 1
        before = fmu.logged
        if op == 0:  # enter initialization, valid or not
            bad = rng.random() < 0.4
            start = rng.choice([float("nan"), float("inf")]) if bad and rng.random() < 0.5 else 0.0
            tol = rng.choice([-1.0, 0.0, float("nan"), 2.0]) if bad else 1e-8
            s = fmu.f("fmi3EnterInitializationMode", C.c_bool, C.c_double, C.c_double, C.c_bool, C.c_double)(
                inst, True, tol, start, False, 0.0
            )
            if st != "inst" or bad:
                expect_refused(s, before)
            elif s == OK:
                st, t = "init", start
        elif op == 1:
            s = fmu.f("fmi3ExitInitializationMode")(inst)
            if st != "init":
                expect_refused(s, before)
            elif s == OK:
                st = "step"
        elif op == 2:  # set: one variable of any kind, a value valid or not
            v = rng.choice(list(V.values()))
            val = rng.choice([0.0, 1.0, 1e-3, -1.0, 1e300, float("nan"), float("-inf")])
            if v["type"] != "Float64":
                continue
            s = set64(inst, arr(C.c_uint32, [v["vr"]]), 1, arr(C.c_double, [val]), 1)
            must = (
                st not in ("inst", "init", "step")
                or not math.isfinite(val)
                or v["vr"] == tvr
                or v["causality"] == "output"
                or (v["causality"] == "parameter" and v["variability"] == "fixed" and st == "step")
                or (v["min"] is not None and val < float(v["min"]))
                or (v["max"] is not None and val > float(v["max"]))
            )
            if must:
                expect_refused(s, before)
        elif op == 3:  # set with nValues != nValueReferences
            v = rng.choice(inputs)
            s = set64(inst, arr(C.c_uint32, [v["vr"]]), 1, arr(C.c_double, [0.0, 0.0]), 2)
            expect_refused(s, before)
        elif op == 4:  # get: some valid and invalid references
            vrs = [rng.choice(all_vr) for _ in range(rng.randint(1, 4))]
            vals = (C.c_double * len(vrs))()
            s = get64(inst, arr(C.c_uint32, vrs), len(vrs), vals, len(vrs))
            kinds = {v["vr"]: v["type"] for v in V.values()}
            # FMI 3.0 reads values in Instantiated too (the start values; issue 30, defect 3)
            if any(kinds.get(x) != "Float64" for x in vrs):
                expect_refused(s, before)
            elif s == OK and not all(math.isfinite(x) for x in vals):
                cnt["nonfinite_ok"] += 1
        elif op in (5, 6, 7):  # steps: mostly valid
            r = rng.random()
            if r < 0.7:
                tt, h = t, rng.choice([1e-3, 5e-4, 2e-3])
            else:
                tt, h = rng.choice(
                    [(t, 0.0), (t, -1e-3), (t, float("nan")), (t, 1e9), (t + 0.5, 1e-3), (float("inf"), 1e-3)]
                )
            s = do_step(tt, h)
            valid = st == "step" and r < 0.7
            if not valid:
                expect_refused(s, before)
            elif s == OK:
                t = t + h
                so, vals = outputs_now()
                if so == OK and not all(math.isfinite(x) for x in vals):
                    cnt["nonfinite_ok"] += 1
            else:
                st = "error"
        elif op == 8:  # functions this FMU never accepts
            name = rng.choice(
                [
                    "fmi3EnterEventMode",
                    "fmi3EnterStepMode",
                    "fmi3EnterConfigurationMode",
                    "fmi3ExitConfigurationMode",
                    "fmi3EvaluateDiscreteStates",
                    "fmi3EnterContinuousTimeMode",
                ]
            )
            expect_refused(fmu.f(name)(inst), before)
        elif op == 9:  # types the FMU does not have
            name = rng.choice(["fmi3GetFloat32", "fmi3GetInt8", "fmi3GetUInt64", "fmi3GetInt16"])
            buf = (C.c_double * 2)()
            s = fmu.f(name, U32P, C.c_size_t, C.c_void_p, C.c_size_t)(
                inst, arr(C.c_uint32, [rng.choice(all_vr)]), 1, C.cast(buf, C.c_void_p), 1
            )
            expect_refused(s, before)
        elif op == 10:  # FMU state round trip
            if st != "step":
                continue
            sp = C.c_void_p()
            if fmu.f("fmi3GetFMUState", C.POINTER(C.c_void_p))(inst, C.byref(sp)) != OK:
                continue
            t0 = t
            ref = []
            for k in range(3):
                if do_step(t0 + k * 1e-3, 1e-3) != OK:
                    break
                ref.append(outputs_now()[1])
            else:
                fmu.f("fmi3SetFMUState", C.c_void_p)(inst, sp)
                again = []
                for k in range(3):
                    do_step(t0 + k * 1e-3, 1e-3)
                    again.append(outputs_now()[1])
                cnt["roundtrips"] += 1
                cnt["roundtrip_bad"] += again != ref
                t = t0 + 3e-3
            states.append((sp, t0))
            if len(states) > 3:
                old, _ = states.pop(0)
                fmu.f("fmi3FreeFMUState", C.POINTER(C.c_void_p))(inst, C.byref(old))
        elif op == 11:  # serialize, corrupt or not, deserialize
            if not states or st != "step":
                continue
            sp, t_at = states[-1]
            size = C.c_size_t()
            if fmu.f("fmi3SerializedFMUStateSize", C.c_void_p, C.POINTER(C.c_size_t))(inst, sp, C.byref(size)) != OK:
                continue
            buf = (C.c_uint8 * size.value)()
            fmu.f("fmi3SerializeFMUState", C.c_void_p, C.c_void_p, C.c_size_t)(inst, sp, buf, size.value)
            corrupt = rng.random() < 0.5
            if corrupt:
                i = rng.randrange(min(64, size.value))
                buf[i] ^= 0xFF
            out = C.c_void_p()
            s = fmu.f("fmi3DeserializeFMUState", C.c_void_p, C.c_size_t, C.POINTER(C.c_void_p))(
                inst, buf, size.value if not corrupt or rng.random() < 0.5 else size.value - 1, C.byref(out)
            )
            if s == OK and not corrupt:  # the copy and the original give the same two steps
                runs = []
                for state in (out.value, sp):
                    fmu.f("fmi3SetFMUState", C.c_void_p)(inst, state)
                    runs.append([(do_step(t_at + k * 1e-3, 1e-3), outputs_now()[1]) for k in range(2)])
                cnt["serial_roundtrips"] += 1
                cnt["serial_bad"] += runs[0] != runs[1]
                t = t_at + 2e-3
                fmu.f("fmi3FreeFMUState", C.POINTER(C.c_void_p))(inst, C.byref(out))
            elif s == OK and out.value:
                fmu.f("fmi3FreeFMUState", C.POINTER(C.c_void_p))(inst, C.byref(out))
        elif op == 12:
            s = fmu.f("fmi3Terminate")(inst)
            if st != "step":
                expect_refused(s, before)
            elif s == OK:
                st = "term"
        elif op == 13:
            s = fmu.f("fmi3Reset")(inst)
            if s == OK:
                st, t = "inst", 0.0
                for sp, _ in states:
                    fmu.f("fmi3FreeFMUState", C.POINTER(C.c_void_p))(inst, C.byref(sp))
                states.clear()
        elif op == 14:  # set time or an output: always refused
            vr = rng.choice([tvr] + outputs)
            s = set64(inst, arr(C.c_uint32, [vr]), 1, arr(C.c_double, [0.0]), 1)
            expect_refused(s, before)
        elif op == 15:  # directional derivative, with the time variable as a known: refused
            if not outputs:
                continue
            sens = (C.c_double * 1)()
            s = fmu.f(
                "fmi3GetDirectionalDerivative", U32P, C.c_size_t, U32P, C.c_size_t, DBLP, C.c_size_t, DBLP, C.c_size_t
            )(inst, arr(C.c_uint32, [outputs[0]]), 1, arr(C.c_uint32, [tvr]), 1, arr(C.c_double, [1.0]), 1, sens, 1)
            expect_refused(s, before)
    for sp, _ in states:
        fmu.f("fmi3FreeFMUState", C.POINTER(C.c_void_p))(inst, C.byref(sp))
    fmu.lib.fmi3FreeInstance.argtypes = [C.c_void_p]
    fmu.lib.fmi3FreeInstance(inst)
    return cnt


def main(argv: list[str]) -> int:
    seed, sequences, calls = int(argv[1]), int(argv[2]), int(argv[3])
    pairs = list(zip(argv[4::2], argv[5::2]))
    total: dict[str, int] = dict(sequences=0, crashes=0, hangs=0, lost=0)
    for k in range(sequences):
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: load the FMUs, run one sequence, report
            os.close(r)
            try:
                rng = random.Random(seed * 100003 + k)
                cnt = run_sequence([Fmu(d, tok) for d, tok in pairs], rng, calls)
                os.write(w, json.dumps(cnt).encode())
            except Exception as e:  # a Python-side failure of the harness: reported, not a crash
                os.write(w, json.dumps({"harness_error": repr(e)}).encode())
            os._exit(0)
        os.close(w)
        deadline = time.time() + 120
        data = b""
        while time.time() < deadline:
            ready, _, _ = select.select([r], [], [], 1.0)
            if ready:
                chunk = os.read(r, 65536)
                if not chunk:
                    break
                data += chunk
        else:
            os.kill(pid, signal.SIGKILL)
            total["hangs"] += 1
        os.close(r)
        _, status = os.waitpid(pid, 0)
        total["sequences"] += 1
        if os.WIFSIGNALED(status) and os.WTERMSIG(status) != signal.SIGKILL:
            total["crashes"] += 1
            continue
        try:
            cnt = json.loads(data.decode() or "{}")
        except ValueError:
            cnt = {}
        if not cnt or "harness_error" in cnt:
            total["lost"] += 1
            print(cnt.get("harness_error", "no report"), file=sys.stderr)
            continue
        for key, v in cnt.items():
            total[key] = total.get(key, 0) + v
    for key, v in total.items():
        print(key, v)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
