// Command coral-verdicts judges Kubernetes objects the way GitOps clients do, for the tests of
// docs/verdicts.md: kstatus (sigs.k8s.io/cli-utils, as Flux's `wait: true` does), the Argo CD
// health script (gopher-lua, sandboxed with the libraries Argo CD opens) and Flux
// `healthCheckExprs` (CEL, evaluated in Flux's order after its observedGeneration check).
//
// Input (stdin): {"objects": [...], "lua": "<script>", "cel": {"Kind": {"current": ..., "failed": ..., "inProgress": ...}}}
// Output (stdout): one verdict per object, in order.
package main

import (
	"context"
	"encoding/json"
	"fmt"
	"os"
	"time"

	"github.com/google/cel-go/cel"
	"github.com/google/cel-go/common/types"
	"github.com/google/cel-go/ext"
	lua "github.com/yuin/gopher-lua"
	"k8s.io/apimachinery/pkg/apis/meta/v1/unstructured"
	utiljson "k8s.io/apimachinery/pkg/util/json"
	"sigs.k8s.io/cli-utils/pkg/kstatus/status"
)

type exprs struct {
	Current    string `json:"current"`
	Failed     string `json:"failed"`
	InProgress string `json:"inProgress"`
}

type input struct {
	Objects []json.RawMessage `json:"objects"`
	Lua     string            `json:"lua"`
	CEL     map[string]exprs  `json:"cel"`
}

type judgement struct {
	Status  string `json:"status"`
	Message string `json:"message"`
}

type verdict struct {
	Kstatus judgement `json:"kstatus"`
	Argo    judgement `json:"argo"`
	Flux    judgement `json:"flux"`
}

func kstatusOf(obj map[string]any) judgement {
	result, err := status.Compute(&unstructured.Unstructured{Object: obj})
	if err != nil {
		return judgement{Status: "Unknown", Message: err.Error()}
	}
	return judgement{Status: string(result.Status), Message: result.Message}
}

// toLua converts decoded JSON into Lua values as Argo CD hands `obj` to its scripts.
func toLua(l *lua.LState, value any) lua.LValue {
	switch v := value.(type) {
	case map[string]any:
		table := l.CreateTable(0, len(v))
		for key, item := range v {
			table.RawSetString(key, toLua(l, item))
		}
		return table
	case []any:
		table := l.CreateTable(len(v), 0)
		for _, item := range v {
			table.Append(toLua(l, item))
		}
		return table
	case string:
		return lua.LString(v)
	case bool:
		return lua.LBool(v)
	case float64:
		return lua.LNumber(v)
	case int64:
		return lua.LNumber(v)
	case json.Number:
		f, _ := v.Float64()
		return lua.LNumber(f)
	case nil:
		return lua.LNil
	}
	return lua.LString(fmt.Sprint(value))
}

// safeOs is the only part of `os` Argo CD's sandbox offers (time and date).
func safeOs(l *lua.LState) int {
	mod := l.NewTable()
	l.SetFuncs(mod, map[string]lua.LGFunction{
		"time": func(l *lua.LState) int { l.Push(lua.LNumber(time.Now().Unix())); return 1 },
	})
	l.Push(mod)
	return 1
}

func argoOf(script string, obj map[string]any) judgement {
	l := lua.NewState(lua.Options{SkipOpenLibs: true})
	defer l.Close()
	for name, open := range map[string]lua.LGFunction{
		lua.LoadLibName: lua.OpenPackage,
		lua.BaseLibName: lua.OpenBase,
		lua.TabLibName:  lua.OpenTable,
	} {
		if err := l.CallByParam(lua.P{Fn: l.NewFunction(open), NRet: 0, Protect: true}, lua.LString(name)); err != nil {
			return judgement{Status: "Error", Message: err.Error()}
		}
	}
	l.PreloadModule(lua.OsLibName, safeOs)
	ctx, cancel := context.WithTimeout(context.Background(), time.Second)
	defer cancel()
	l.SetContext(ctx)
	l.SetGlobal("obj", toLua(l, obj))
	if err := l.DoString(script); err != nil {
		return judgement{Status: "Error", Message: err.Error()}
	}
	table, ok := l.Get(-1).(*lua.LTable)
	if !ok {
		return judgement{Status: "Error", Message: "the script returned no table"}
	}
	return judgement{
		Status:  lua.LVAsString(table.RawGetString("status")),
		Message: lua.LVAsString(table.RawGetString("message")),
	}
}

func evaluate(expression string, obj map[string]any) (bool, error) {
	env, err := cel.NewEnv(
		cel.HomogeneousAggregateLiterals(),
		cel.EagerlyValidateDeclarations(true),
		cel.DefaultUTCTimeZone(true),
		cel.CrossTypeNumericComparisons(true),
		cel.OptionalTypes(),
		ext.Strings(),
		ext.Sets(),
		ext.Encoders(),
	)
	if err != nil {
		return false, err
	}
	parsed, issues := env.Parse(expression)
	if issues != nil && issues.Err() != nil {
		return false, issues.Err()
	}
	program, err := env.Program(parsed, cel.EvalOptions(cel.OptOptimize), cel.InterruptCheckFrequency(100))
	if err != nil {
		return false, err
	}
	value, _, err := program.ContextEval(context.Background(), obj)
	if err != nil {
		return false, err
	}
	result, ok := value.(types.Bool)
	if !ok {
		return false, fmt.Errorf("%q is not a boolean expression", expression)
	}
	return bool(result), nil
}

// fluxOf follows Flux's CEL status evaluator: a stale observedGeneration is InProgress, then
// inProgress, failed and current in that order, the first true one wins; none true is InProgress.
// An evaluation error leaves the status Unknown, so Flux keeps polling until its timeout.
func fluxOf(checks map[string]exprs, obj map[string]any) judgement {
	kind, _ := obj["kind"].(string)
	check, ok := checks[kind]
	if !ok {
		return judgement{Status: "Unknown", Message: "no expressions for kind " + kind}
	}
	u := unstructured.Unstructured{Object: obj}
	observed, hasObserved, _ := unstructured.NestedFieldNoCopy(obj, "status", "observedGeneration")
	if hasObserved && fmt.Sprint(observed) != fmt.Sprint(u.GetGeneration()) {
		return judgement{Status: "InProgress", Message: "observedGeneration is behind"}
	}
	for _, step := range []struct{ expr, status string }{
		{check.InProgress, "InProgress"}, {check.Failed, "Failed"}, {check.Current, "Current"},
	} {
		if step.expr == "" {
			continue
		}
		result, err := evaluate(step.expr, obj)
		if err != nil {
			return judgement{Status: "Unknown", Message: err.Error()}
		}
		if result {
			return judgement{Status: step.status}
		}
	}
	return judgement{Status: "InProgress"}
}

func main() {
	var in input
	decoder := json.NewDecoder(os.Stdin)
	if err := decoder.Decode(&in); err != nil {
		fmt.Fprintln(os.Stderr, "coral-verdicts: cannot read input:", err)
		os.Exit(2)
	}
	out := make([]verdict, 0, len(in.Objects))
	for _, raw := range in.Objects {
		// Decoded as the apiserver's clients decode, integers as int64, which kstatus expects.
		obj := map[string]any{}
		if err := utiljson.Unmarshal(raw, &obj); err != nil {
			fmt.Fprintln(os.Stderr, "coral-verdicts: cannot read an object:", err)
			os.Exit(2)
		}
		out = append(out, verdict{Kstatus: kstatusOf(obj), Argo: argoOf(in.Lua, obj), Flux: fluxOf(in.CEL, obj)})
	}
	if err := json.NewEncoder(os.Stdout).Encode(out); err != nil {
		os.Exit(1)
	}
}
