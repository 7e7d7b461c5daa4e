// coral-cri talks to a container runtime through the CRI, as the kubelet does: a small client for
// tests and people working on real robots. crictl would do, but its module is not served by the Go
// module proxy, and this project builds only from Go modules.
//
// Usage:
//
//	coral-cri --endpoint unix:///run/containerd/containerd.sock ps [-a] [-q] [--label k=v]...
//	coral-cri --endpoint ... pods [-q] [--label k=v]...
//	coral-cri --endpoint ... inspect CONTAINER-ID
//	coral-cri --endpoint ... stop [--timeout SECONDS] CONTAINER-ID   (timeout 0 kills at once)
//	coral-cri --endpoint ... images
//	coral-cri --endpoint ... version
//
// Lists and inspections print JSON (the CRI messages), or one ID per line with -q.
package main

import (
	"context"
	"encoding/json"
	"flag"
	"fmt"
	"os"
	"strings"
	"time"

	"google.golang.org/grpc"
	"google.golang.org/grpc/credentials/insecure"
	runtimeapi "k8s.io/cri-api/pkg/apis/runtime/v1"
)

type labels map[string]string

func (l labels) String() string { return fmt.Sprint(map[string]string(l)) }

func (l labels) Set(value string) error {
	key, val, ok := strings.Cut(value, "=")
	if !ok || key == "" {
		return fmt.Errorf("%q is not KEY=VALUE", value)
	}
	l[key] = val
	return nil
}

func fail(format string, args ...any) {
	fmt.Fprintf(os.Stderr, "coral-cri: "+format+"\n", args...)
	os.Exit(1)
}

func printJSON(value any) {
	out, err := json.MarshalIndent(value, "", "  ")
	if err != nil {
		fail("%v", err)
	}
	fmt.Println(string(out))
}

func main() {
	endpoint := flag.String("endpoint", "unix:///run/containerd/containerd.sock", "CRI endpoint")
	timeout := flag.Duration("request-timeout", 30*time.Second, "timeout of each CRI call")
	flag.Parse()
	if flag.NArg() == 0 {
		fail("give a command: ps, pods, inspect, stop, images, version")
	}
	conn, err := grpc.NewClient(*endpoint, grpc.WithTransportCredentials(insecure.NewCredentials()))
	if err != nil {
		fail("connecting to %s: %v", *endpoint, err)
	}
	defer conn.Close()
	runtime := runtimeapi.NewRuntimeServiceClient(conn)
	images := runtimeapi.NewImageServiceClient(conn)
	ctx, cancel := context.WithTimeout(context.Background(), *timeout)
	defer cancel()

	command, rest := flag.Arg(0), flag.Args()[1:]
	sub := flag.NewFlagSet(command, flag.ExitOnError)
	quiet := sub.Bool("q", false, "print IDs only")
	all := sub.Bool("a", false, "include exited containers")
	stopTimeout := sub.Int64("timeout", 10, "seconds before SIGKILL")
	selector := labels{}
	sub.Var(selector, "label", "KEY=VALUE label to match (repeatable)")
	if err := sub.Parse(rest); err != nil {
		fail("%v", err)
	}

	switch command {
	case "ps":
		filter := &runtimeapi.ContainerFilter{LabelSelector: selector}
		if !*all {
			filter.State = &runtimeapi.ContainerStateValue{State: runtimeapi.ContainerState_CONTAINER_RUNNING}
		}
		resp, err := runtime.ListContainers(ctx, &runtimeapi.ListContainersRequest{Filter: filter})
		if err != nil {
			fail("ps: %v", err)
		}
		if *quiet {
			for _, c := range resp.Containers {
				fmt.Println(c.Id)
			}
			return
		}
		printJSON(resp.Containers)
	case "pods":
		filter := &runtimeapi.PodSandboxFilter{LabelSelector: selector}
		resp, err := runtime.ListPodSandbox(ctx, &runtimeapi.ListPodSandboxRequest{Filter: filter})
		if err != nil {
			fail("pods: %v", err)
		}
		if *quiet {
			for _, p := range resp.Items {
				fmt.Println(p.Id)
			}
			return
		}
		printJSON(resp.Items)
	case "inspect":
		if sub.NArg() != 1 {
			fail("inspect needs one container ID")
		}
		resp, err := runtime.ContainerStatus(ctx, &runtimeapi.ContainerStatusRequest{ContainerId: sub.Arg(0)})
		if err != nil {
			fail("inspect %s: %v", sub.Arg(0), err)
		}
		printJSON(resp.Status)
	case "stop":
		if sub.NArg() != 1 {
			fail("stop needs one container ID")
		}
		_, err := runtime.StopContainer(ctx, &runtimeapi.StopContainerRequest{ContainerId: sub.Arg(0), Timeout: *stopTimeout})
		if err != nil {
			fail("stop %s: %v", sub.Arg(0), err)
		}
		fmt.Println(sub.Arg(0))
	case "images":
		resp, err := images.ListImages(ctx, &runtimeapi.ListImagesRequest{})
		if err != nil {
			fail("images: %v", err)
		}
		printJSON(resp.Images)
	case "version":
		resp, err := runtime.Version(ctx, &runtimeapi.VersionRequest{})
		if err != nil {
			fail("version: %v", err)
		}
		printJSON(resp)
	default:
		fail("unknown command %q: use ps, pods, inspect, stop, images, version", command)
	}
}
